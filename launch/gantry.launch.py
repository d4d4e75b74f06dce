"""
Launch a two-axis gantry: two simulated lead screw axes, x_axis and y_axis.

    ros2 launch leadscrew_sim gantry.launch.py
    ros2 launch leadscrew_sim gantry.launch.py preset:=tr8x8 robot_state_publisher:=true

Each axis is leadscrew_sim.launch.py in its own namespace with its own joint
prefix: /x_axis/axis/joint_states carries x_screw_joint and x_nut_joint,
/y_axis/axis/joint_states y_screw_joint and y_nut_joint. Both record into their own
folder below record_dir (<record_dir>/x_axis, <record_dir>/y_axis). The two
URDF trees (x_base_link, y_base_link) are not joined: mount them with a static
transform of your machine (e.g. y_base_link on x_nut_link).
"""
import os

from ament_index_python.packages import get_package_share_directory
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument, GroupAction, IncludeLaunchDescription
from launch.launch_description_sources import PythonLaunchDescriptionSource
from launch.substitutions import LaunchConfiguration, PathJoinSubstitution

#: (axis namespace, joint prefix)
AXES = (('x_axis', 'x_'), ('y_axis', 'y_'))

#: Arguments passed through to both axes: (name, default, description).
SHARED = (
    ('preset', 'tr12x3', 'preset of both axes'),
    ('params_file', '', 'parameter file for both axes (empty: none)'),
    ('clock_mode', 'realtime', 'realtime, stepped or lockstep'),
    ('use_sim_time', 'false', 'use /clock for the ROS time of the nodes'),
    ('record', 'true', 'record each axis to an MCAP file'),
    ('record_dir', 'runs', 'each axis records into <record_dir>/<axis namespace>'),
    ('robot_state_publisher', 'false', 'start a robot_state_publisher per axis'),
)


def generate_launch_description():
    """Declare the shared arguments and include the single-axis launch file twice."""
    axis_launch = os.path.join(
        get_package_share_directory('leadscrew_sim'), 'launch', 'leadscrew_sim.launch.py')
    actions = [DeclareLaunchArgument(name, default_value=default, description=description)
               for name, default, description in SHARED]
    for namespace, prefix in AXES:
        arguments = {name: LaunchConfiguration(name) for name, _, _ in SHARED}
        arguments.update(
            namespace=namespace, joint_prefix=prefix,
            record_dir=PathJoinSubstitution([LaunchConfiguration('record_dir'), namespace]))
        actions.append(GroupAction(scoped=True, actions=[IncludeLaunchDescription(
            PythonLaunchDescriptionSource(axis_launch),
            launch_arguments=arguments.items())]))
    return LaunchDescription(actions)
