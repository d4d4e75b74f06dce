"""
Launch one simulated lead screw axis: leadscrew_sim_node, optionally robot_state_publisher.

    ros2 launch leadscrew_sim leadscrew_sim.launch.py namespace:=z_axis joint_prefix:=z_
    ros2 launch leadscrew_sim leadscrew_sim.launch.py params_file:=/path/to/my_axis.yaml

Parameter precedence (the later wins): the preset (config/<preset>.yaml, or a
YAML path), then params_file, then the explicit launch arguments (joint_prefix,
clock_mode, use_sim_time, record, record_dir), which are always passed. A
parameter file should use the `/**:` key so it applies whatever the namespace.

With robot_state_publisher:=true the package's URDF
(urdf/leadscrew_axis.urdf.xacro) is rendered with xacro, with the joint prefix
and the lead, hand, backlash, stroke, screw diameter and motor torque of the
preset and the parameter file, so the model shown matches the simulated axis.
It runs in the node's namespace, its joint_states remapped to the node's
axis/joint_states.
"""
import os

from ament_index_python.packages import get_package_share_directory
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument, OpaqueFunction
from launch.substitutions import Command, FindExecutable, LaunchConfiguration
from launch_ros.actions import Node
from launch_ros.parameter_descriptions import ParameterValue
from leadscrew_sim.io.description import xacro_args
from leadscrew_sim.io.topics import graph_name
import yaml

PACKAGE = 'leadscrew_sim'

#: (name, default, description) of every launch argument.
ARGUMENTS = (
    ('preset', 'tr12x3', 'preset name (config/<name>.yaml) or a YAML path: the defaults of '
                         'the physical parameters'),
    ('params_file', '', 'ROS 2 parameter file for the node (empty: none); its values override '
                        'the preset, the explicit launch arguments override it'),
    ('namespace', '', 'namespace of the node (and of robot_state_publisher)'),
    ('joint_prefix', '', 'prefix of the joint names screw_joint and nut_joint (and of the '
                         'URDF links)'),
    ('clock_mode', 'realtime', 'realtime, stepped or lockstep'),
    ('use_sim_time', 'false', 'use /clock for the ROS time of the nodes'),
    ('record', 'true', 'record commands and states to an MCAP file'),
    ('record_dir', 'runs', 'directory of the MCAP recordings'),
    ('robot_state_publisher', 'false', 'also start robot_state_publisher with the URDF'),
)


def _as_bool(name, text):
    value = yaml.safe_load(text) if text.strip() else None
    if not isinstance(value, bool):
        raise ValueError(f"launch argument '{name}': {text!r} is not true or false")
    return value


def _ros_parameters(path):
    """Return the ros__parameters of a parameter file (any node key), or {}."""
    with open(path) as fh:
        doc = yaml.safe_load(fh) or {}
    for section in doc.values() if isinstance(doc, dict) else ():
        if isinstance(section, dict) and isinstance(section.get('ros__parameters'), dict):
            return dict(section['ros__parameters'])
    return {}


def _preset_path(preset, share):
    if preset.endswith(('.yaml', '.yml')):
        return preset
    dirs = [os.environ.get('LEADSCREW_SIM_CONFIG', ''), os.path.join(share, 'config')]
    for d in dirs:
        path = os.path.join(d, preset + '.yaml')
        if d and os.path.isfile(path):
            return path
    return None


def _xacro_mappings(preset, params_file, share, logger):
    """Return the xacro arguments of the axis that preset and params_file describe."""
    values = {}
    path = _preset_path(preset, share)
    if path is None:
        logger.warning(f'preset {preset!r} not found: the URDF uses its default geometry')
    else:
        values.update(_ros_parameters(path))
    if params_file:
        values.update(_ros_parameters(params_file))
    mappings = xacro_args(values)           # the package's one preset -> xacro mapping
    del mappings['prefix']
    return mappings


def _launch_setup(context):
    arg = {name: LaunchConfiguration(name).perform(context) for name, _, _ in ARGUMENTS}
    share = get_package_share_directory(PACKAGE)
    params_file = arg['params_file'].strip()
    if params_file and not os.path.isfile(params_file):
        raise FileNotFoundError(f"launch argument 'params_file': no file {params_file!r}")
    # Strings as strings (launch_ros would read a prefix '1' or a directory '2024' as YAML).
    explicit = {name: ParameterValue(arg[name], value_type=str)
                for name in ('preset', 'joint_prefix', 'clock_mode', 'record_dir')}
    explicit['use_sim_time'] = _as_bool('use_sim_time', arg['use_sim_time'])
    explicit['record'] = _as_bool('record', arg['record'])
    parameters = ([params_file] if params_file else []) + [explicit]
    actions = [Node(
        package=PACKAGE, executable='leadscrew_sim_node', name='leadscrew_sim_node',
        namespace=arg['namespace'], parameters=parameters, output='screen')]

    if _as_bool('robot_state_publisher', arg['robot_state_publisher']):
        import launch.logging
        logger = launch.logging.get_logger('leadscrew_sim.launch')
        mappings = {'prefix': arg['joint_prefix']}
        mappings.update(_xacro_mappings(arg['preset'], params_file, share, logger))
        command = [FindExecutable(name='xacro'), ' ',
                   os.path.join(share, 'urdf', 'leadscrew_axis.urdf.xacro')]
        for name, value in mappings.items():
            command += [' ', f'{name}:={value}']
        description = ParameterValue(Command(command), value_type=str)
        actions.append(Node(
            package='robot_state_publisher', executable='robot_state_publisher',
            name='robot_state_publisher', namespace=arg['namespace'], output='screen',
            remappings=[('joint_states', graph_name('joint_states'))],
            parameters=[{'robot_description': description,
                         'use_sim_time': explicit['use_sim_time']}]))
    return actions


def generate_launch_description():
    """Declare the arguments; the actions are made once they are known."""
    return LaunchDescription(
        [DeclareLaunchArgument(name, default_value=default, description=description)
         for name, default, description in ARGUMENTS]
        + [OpaqueFunction(function=_launch_setup)])
