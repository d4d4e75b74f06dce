"""
The servo drive over DDS from another process: command intake as topic-based ros2_control sends it.

The node runs as a real process; commands go out from the test process as
JointState and Float64 messages. The targets are nut positions [m]; the
node must bring the nut there (a position loop with an integral settles to
the target at the motor encoder, and the nut is within the contact
compliance of it on a backlash-free, loaded flank).
"""
import math

from diagnostic_msgs.msg import DiagnosticArray
from helpers import command_publisher, NODE, Ros, start_node, wait_states
import pytest
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import JointState
from std_msgs.msg import Bool, Float64
from std_srvs.srv import Trigger

NAN = float('nan')
LATCHED = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                     durability=DurabilityPolicy.TRANSIENT_LOCAL)


def diag_value(diags, key):
    """Value of a key in the latest diagnostics message, or None."""
    for kv in (diags[-1].status[0].values if diags else []):
        if kv.key == key:
            return kv.value
    return None


def finite(msg):
    return all(math.isfinite(v) for v in list(msg.position) + list(msg.velocity)
               + list(msg.effort))


def nut(states):
    return states[-1].position[1]


def send(ros, pub, msg, seconds, period=0.01):
    """Publish ``msg`` every ``period`` s for ``seconds`` (as a controller does)."""
    n = max(1, int(seconds / period))
    for _ in range(n):
        pub.publish(msg)
        ros.spin_for(period)


@pytest.mark.timeout(180)
def test_position_only_joint_state_moves_the_nut_to_the_target(run_exe, ros):
    proc = start_node(run_exe, 'preset:=tr12x3', 'command_timeout:=1.0')
    states = ros.collect(JointState, 'axis/joint_states')
    wait_states(ros, states, proc)
    pub = command_publisher(ros, 'axis/joint_commands', JointState)
    x0 = nut(states)
    for target in (x0 + 0.004, x0 - 0.002):
        msg = JointState(name=['nut_joint'], position=[target])    # no velocity, no effort
        send(ros, pub, msg, 2.0)
        # Thread stiction makes the last micrometres a slow stick-slip creep of the PI loop.
        for _ in range(60):
            if abs(nut(states) - target) < 10e-6:
                break
            send(ros, pub, msg, 0.1)
        assert abs(nut(states) - target) < 10e-6, (target, nut(states))
    assert all(finite(s) for s in states)


@pytest.mark.timeout(180)
def test_nan_padding_and_separate_messages_are_accepted(run_exe, ros):
    # The URDF's command interfaces are position and velocity: joint_command_mode position.
    proc = start_node(run_exe, 'preset:=tr12x3', 'command_timeout:=1.0',
                      'joint_command_mode:=position')
    states = ros.collect(JointState, 'axis/joint_states')
    diags = ros.collect(DiagnosticArray, 'diagnostics')
    wait_states(ros, states, proc)
    pub = command_publisher(ros, 'axis/joint_commands', JointState)
    x0 = nut(states)
    # NaN padding: another joint in the message, NaN for what is not commanded.
    padded = JointState(name=['other_joint', 'nut_joint'], position=[NAN, x0 + 0.003],
                        velocity=[NAN, NAN], effort=[NAN, NAN])
    send(ros, pub, padded, 2.0)
    for _ in range(60):
        if abs(nut(states) - (x0 + 0.003)) < 10e-6:
            break
        send(ros, pub, padded, 0.1)
    assert abs(nut(states) - (x0 + 0.003)) < 10e-6
    # One message per interface: a position, then a velocity feed-forward of 0.
    target = x0 + 0.001
    for _ in range(500):
        pub.publish(JointState(name=['nut_joint'], position=[target]))
        pub.publish(JointState(name=['nut_joint'], velocity=[0.0]))
        ros.spin_for(0.01)
        if _ > 200 and abs(nut(states) - target) < 10e-6:
            break
    assert abs(nut(states) - target) < 10e-6
    ros.spin_until(lambda: diag_value(diags, 'drive_mode') is not None, 5.0)
    assert diag_value(diags, 'drive_mode') == 'position'
    assert diag_value(diags, 'rejected_commands') == '0'
    assert all(finite(s) for s in states)


@pytest.mark.timeout(180)
def test_velocity_command_float64_and_its_timeout_hold_the_load(run_exe, ros):
    # tr8x8 back-drives: without a drive holding it the vertical load would fall. It falls
    # before the first command, past the preset's overspeed trip: off here.
    proc = start_node(run_exe, 'preset:=tr8x8', 'command_timeout:=0.3', 'max_screw_velocity:=0.0')
    states = ros.collect(JointState, 'axis/joint_states')
    wait_states(ros, states, proc)
    pub = command_publisher(ros, 'velocity_command')
    x0 = nut(states)
    # 10 mm/s until the nut has travelled 5 mm, then silence. The deadline leaves
    # room for discovery: the node drops what arrives before it has matched the
    # publisher, and the test's side matches first.
    for _ in range(100):
        send(ros, pub, Float64(data=0.01), 0.1)
        if nut(states) - x0 > 0.005:
            break
    assert nut(states) - x0 > 0.005
    assert states[-1].velocity[1] == pytest.approx(0.01, rel=0.2)
    ros.spin_for(1.0)                                # stale: quick stop, then hold
    x_hold = nut(states)
    ros.spin_for(3.0)
    assert abs(nut(states) - x_hold) < 10e-6
    assert all(finite(s) for s in states)


@pytest.mark.timeout(120)
def test_switches_are_latched_topics_and_clear_fault_answers(run_exe):
    proc = start_node(run_exe, 'preset:=tr12x3')
    ros = Ros()
    try:
        got = {t: [] for t in ('limit_switch/min', 'limit_switch/max', 'home_switch')}
        states = ros.collect(JointState, 'axis/joint_states')
        wait_states(ros, states, proc)
        ros.spin_for(0.5)
        for topic, out in got.items():       # a late subscriber gets the state at once
            ros.node.create_subscription(Bool, topic, out.append, LATCHED)
        assert ros.spin_until(lambda: all(got.values()), 10.0), {t: len(v) for t, v in got.items()}
        assert [got[t][-1].data for t in got] == [False, False, False]
        r = ros.call(Trigger, f'{NODE}/clear_fault', Trigger.Request())
        assert r.success and 'no drive fault' in r.message
    finally:
        ros.close()
