"""
The node's Foxglove live view (parameter foxglove_port), checked from a client of our own.

The node runs as a real process; the client (test/foxglove_client.py) is
written from Foxglove's published WebSocket protocol with websocket-client,
and rosbags decodes the CDR payloads and parses the advertised ros2msg
schemas: nothing of leadscrew_sim reads what the server sends.
"""
import math

from foxglove_client import FoxgloveClient, free_port
from helpers import NODE, start_node
from leadscrew_sim.core import load_preset
import pytest
from rcl_interfaces.srv import SetParameters
from rclpy.parameter import Parameter as RosParameter
from rosbags.typesys import get_types_from_msg, Stores, get_typestore

TS = get_typestore(Stores.ROS2_JAZZY)

#: Every topic the node publishes, with its type (the recorded-only ones come along).
PUBLISHED = {
    '/axis/joint_states': 'sensor_msgs/msg/JointState',
    '/nut_position': 'std_msgs/msg/Float64',
    '/thread_force': 'geometry_msgs/msg/WrenchStamped',
    '/sim/joint_states': 'sensor_msgs/msg/JointState',
    '/diagnostics': 'diagnostic_msgs/msg/DiagnosticArray',
    '/limit_switch/min': 'std_msgs/msg/Bool',
    '/limit_switch/max': 'std_msgs/msg/Bool',
    '/home_switch': 'std_msgs/msg/Bool',
    '/axis/robot_description': 'std_msgs/msg/String',
    '/tf_static': 'tf2_msgs/msg/TFMessage',
    '/tf': 'tf2_msgs/msg/TFMessage',
}


def float64(value):
    """Return the CDR of a std_msgs/Float64 (rosbags' serializer)."""
    return bytes(TS.serialize_cdr(TS.types['std_msgs/msg/Float64'](data=value),
                                  'std_msgs/msg/Float64'))


def decode(client, sub, type_name):
    """Decode every message of a subscription with rosbags; return [(timestamp, message)]."""
    return [(t, TS.deserialize_cdr(p, type_name)) for t, p in client.data[sub]]


def diag_value(msg, key):
    """Return a key's value in a DiagnosticArray."""
    return next(kv.value for kv in msg.status[0].values if kv.key == key)


@pytest.fixture
def live_node(run_exe):
    """Start a node at 1 kHz serving Foxglove; yield (process, client)."""
    port = free_port()
    # the client's torque runs the axis past the preset's overspeed trip: off here
    proc = start_node(run_exe, f'foxglove_port:={port}', 'max_screw_velocity:=0.0')
    client = FoxgloveClient(port, timeout=60.0, proc=proc)
    yield proc, client
    client.close()


@pytest.mark.timeout(60)
def test_advertise_and_joint_states_decode(live_node):
    proc, c = live_node
    assert c.wait_channels(PUBLISHED), (sorted(c.channels), proc.output())
    for topic, type_name in PUBLISHED.items():
        ch = c.channels[topic]
        assert (ch['encoding'], ch['schemaName'], ch['schemaEncoding']) == (
            'cdr', type_name, 'ros2msg'), ch
        # The schema is a full ros2msg definition: rosbags parses it into the type's fields.
        types = get_types_from_msg(ch['schema'], type_name)
        ours = [name for name, _ in types[type_name][1]]
        theirs = [name for name, _ in TS.fielddefs[type_name][1]]
        assert ours == theirs, (topic, ours, theirs)
    sub = c.subscribe('/axis/joint_states')
    assert c.poll_until(lambda: len(c.data[sub]) >= 300, 20.0), proc.output()
    msgs = decode(c, sub, 'sensor_msgs/msg/JointState')
    assert list(msgs[0][1].name) == ['screw_joint', 'nut_joint']
    stamps = [m.header.stamp.sec * 10**9 + m.header.stamp.nanosec for _t, m in msgs]
    # The messageData timestamp is the message's log time: its stamp (no sensor delay).
    assert [t for t, _m in msgs] == stamps
    # 1 kHz: consecutive stamps 1 ms apart while the client keeps up (the queue drops none).
    steps = [b - a for a, b in zip(stamps, stamps[1:])]
    assert sum(s == 1_000_000 for s in steps) >= 0.95 * len(steps), steps[:20]
    # axis/robot_description and /tf_static are latched: a late subscriber gets them at once.
    desc = c.subscribe('/axis/robot_description')
    static = c.subscribe('/tf_static')
    tf = c.subscribe('/tf')
    assert c.poll_until(lambda: c.data[desc] and c.data[static] and len(c.data[tf]) > 10, 10.0)
    urdf = decode(c, desc, 'std_msgs/msg/String')[0][1].data
    assert '<robot' in urdf and 'nut_joint' in urdf
    frames = {t.child_frame_id for _s, m in decode(c, tf, 'tf2_msgs/msg/TFMessage')
              for t in m.transforms}
    assert frames, 'no moving frames on /tf'


@pytest.mark.timeout(60)
def test_torque_command_from_client_moves_nut(live_node):
    proc, c = live_node
    assert c.wait_channels(['/axis/joint_states', '/diagnostics']), proc.output()
    sub = c.subscribe('/axis/joint_states')
    diag = c.subscribe('/diagnostics')
    assert c.poll_until(lambda: len(c.data[sub]) > 10, 20.0)
    x0 = decode(c, sub, 'sensor_msgs/msg/JointState')[-1][1].position[1]
    chan = c.advertise('torque_command', 'std_msgs/msg/Float64')
    torque = 0.3
    for _ in range(12):                          # 0.6 s, within the 0.5 s command timeout
        c.publish(chan, float64(torque))
        c.poll_until(lambda: False, 0.05)
    states = decode(c, sub, 'sensor_msgs/msg/JointState')
    applied = [m for _t, m in states if m.effort[0] == torque]
    assert len(applied) > 300, proc.output()
    dx = applied[-1].position[1] - x0
    # tr12x3 is right-handed: a positive motor torque moves the nut toward -x (doc/model.md).
    sign = -1.0 if load_preset('tr12x3').hand == 'right' else 1.0
    assert abs(dx) > 1e-3 and math.copysign(1.0, dx) == sign, dx
    # The commands went through the node's intake: counted like ROS commands.
    garbage = c.advertise('velocity_command', 'std_msgs/msg/Float64')
    c.publish(garbage, b"\x00\x01\x00\x00\x01")           # 1 byte: not a Float64
    c.publish(garbage, float64(float('nan')))            # NaN: refused

    def last_diag():
        return decode(c, diag, 'diagnostic_msgs/msg/DiagnosticArray')[-1][1]
    # The truncated one never reaches the intake (counted as malformed); the NaN is
    # refused by the intake, as a ROS message would be.
    assert c.poll_until(lambda: len(c.data[diag]) >= 1 and int(diag_value(
        last_diag(), 'rejected_commands')) >= 1 and diag_value(
        last_diag(), 'foxglove_malformed') == '1', 5.0), proc.output()
    last = last_diag()
    assert int(diag_value(last, 'commands')) >= 12
    assert diag_value(last, 'foxglove_dropped') == '0'


@pytest.mark.timeout(60)
def test_parameters_get_set_and_batch_refusal(live_node, ros):
    proc, c = live_node
    got = c.get_parameters(['backlash', 'update_rate', 'preset'], 'get1')
    assert got['update_rate'] == 1000.0 and got['preset'] == 'tr12x3', got
    everything = c.get_parameters([], 'all')          # the Parameters panel asks for all
    assert {'backlash', 'mu_k', 'update_rate', 'foxglove_port'} <= set(everything)
    b0 = got['backlash']
    assert c.set_parameters({'backlash': 5e-5}, 'set1') == {'backlash': 5e-5}
    assert c.get_parameters(['backlash'], 'get2') == {'backlash': 5e-5}
    # An integer for a double parameter is taken as that number (as with ros2 param set).
    assert c.set_parameters({'backlash': 0}, 'set2') == {'backlash': 0.0}
    # A batch with one bad value is refused whole, with the node's reason as a status.
    out = c.set_parameters({'backlash': 7e-5, 'mu_k': -1.0}, 'set3')
    assert out['backlash'] == 0.0 and out['mu_k'] != -1.0, out
    assert any('mu_k' in s['message'] for s in c.statuses), c.statuses
    # Read-only parameters stay.
    assert c.set_parameters({'update_rate': 10.0}, 'set4') == {'update_rate': 1000.0}
    assert c.get_parameters(['backlash'], 'get3') == {'backlash': 0.0}
    assert b0 != 0.0
    # A change over ROS reaches a client that follows the parameter.
    c.subscribe_parameters(['backlash'])
    c.poll_until(lambda: False, 0.3)
    req = SetParameters.Request(parameters=[
        RosParameter('backlash', value=3e-5).to_parameter_msg()])
    assert ros.call(SetParameters, f'{NODE}/set_parameters', req).results[0].successful
    assert c.poll_until(lambda: any(
        m.get('id') is None and {'name': 'backlash', 'type': 'float64', 'value': 3e-5}
        in m['parameters'] for m in c.parameter_values), 10.0), c.parameter_values[-3:]
