"""
The offline command line (``python -m leadscrew_sim.cli``) and leadscrew_sim.io.messages.

The CLI runs as a real subprocess; files are checked with independent readers
(mcap + mcap_ros2, rosbags, rclpy).
"""
import random
import re
import struct
import threading
import time

from helpers import cli, cli_ok, NS
from leadscrew_sim.io import cdr as C, messages as M
from leadscrew_sim.io.msgdefs import cdr_length
import pytest


@pytest.fixture(scope='module')
def sim_file(tmp_path_factory):
    """Return a 1 s, 1 kHz simulate recording of the default preset (sine torque)."""
    path = tmp_path_factory.mktemp('sim') / 'run.mcap'
    cli_ok('simulate', '--duration', 1.0, '--profile', 'sine', '--amplitude', 0.2,
           '--frequency', 2.0, '--output', path, '--quiet')
    return path


# ---------------------------------------------------------------------------
# messages.py against rclpy
# ---------------------------------------------------------------------------

def _padding(layout):
    """
    Return the padding byte offsets of a CDR payload described by ``layout``.

    ``layout``: list of ('u32'|'stamp'|'f64', None) or ('str', text) items, walked
    with CDR alignment relative to the 4-byte encapsulation header.
    """
    pos, pads = 4, set()

    def align(n):
        nonlocal pos
        pad = (-(pos - 4)) % n
        pads.update(range(pos, pos + pad))
        pos += pad

    for kind, arg in layout:
        if kind == 'u32':
            align(4)
            pos += 4
        elif kind == 'stamp':
            align(4)
            pos += 8
        elif kind == 'f64':
            align(8)
            pos += 8
        elif kind == 'str':
            align(4)
            pos += 4 + len(arg.encode()) + 1
    return pads, pos


def _js_layout(names):
    lay = [('stamp', None), ('str', ''), ('u32', None)] + [('str', n) for n in names]
    for _ in range(3):
        lay += [('u32', None)] + [('f64', None)] * len(names)
    return lay


@pytest.mark.parametrize('prefix', ['', 'left/', 'a'])
def test_state_encoder_matches_rclpy(prefix):
    """Encoded bytes equal serialize_message except in the padding (uninitialized in rclpy)."""
    from geometry_msgs.msg import WrenchStamped
    from rclpy.serialization import deserialize_message, serialize_message
    from rosgraph_msgs.msg import Clock
    from sensor_msgs.msg import JointState
    from std_msgs.msg import Float64
    enc = M.StateEncoder(prefix)
    rng = random.Random(7)
    names = [prefix + 'screw_joint', prefix + 'nut_joint']
    assert list(enc.joint_names) == names
    js_pads, js_len = _padding(_js_layout(names))
    wr_pads, wr_len = _padding([('stamp', None), ('str', '')] + [('f64', None)] * 6)
    for _ in range(50):
        stamp = rng.randrange(0, 2 ** 31 * NS)
        v = [rng.uniform(-1e3, 1e3) for _ in range(6)]
        m = JointState(name=names, position=v[0:2], velocity=v[2:4], effort=v[4:6])
        m.header.stamp.sec, m.header.stamp.nanosec = divmod(stamp, NS)
        ref = serialize_message(m)
        ref = ref[:cdr_length('sensor_msgs/msg/JointState', ref)]
        mine = enc.joint_states(stamp, v)
        assert len(mine) == len(ref) == js_len
        diff = {i for i in range(len(ref)) if mine[i] != ref[i]}
        assert diff <= js_pads, sorted(diff - js_pads)
        assert all(mine[i] == 0 for i in js_pads)
        back = deserialize_message(mine, JointState)
        assert list(back.name) == names and list(back.position) == v[0:2]
        assert list(back.velocity) == v[2:4] and list(back.effort) == v[4:6]
        assert back.header.stamp.sec * NS + back.header.stamp.nanosec == stamp

        w = WrenchStamped()
        w.header.stamp.sec, w.header.stamp.nanosec = divmod(stamp, NS)
        w.wrench.force.x, w.wrench.torque.x = v[0], v[1]
        ref = serialize_message(w)[:wr_len]
        mine = enc.thread_force(stamp, (v[0], v[1]))
        assert len(mine) == wr_len
        assert {i for i in range(wr_len) if mine[i] != ref[i]} <= wr_pads
        assert C.decode_wrench_stamped(mine) == (stamp, (v[0], 0.0, 0.0), (v[1], 0.0, 0.0))

        # No padding in Float64 and Clock: byte for byte.
        assert enc.nut_position(None, (v[2],)) == serialize_message(Float64(data=v[2]))
        assert C.encode_float64(v[3]) == serialize_message(Float64(data=v[3]))
        c = Clock()
        c.clock.sec, c.clock.nanosec = divmod(stamp, NS)
        assert enc.clock(stamp, ()) == serialize_message(c)
        assert C.decode_joint_state(enc.joint_states(stamp, v)) == (
            stamp, names, tuple(v[0:2]), tuple(v[2:4]), tuple(v[4:6]))


# ---------------------------------------------------------------------------
# simulate
# ---------------------------------------------------------------------------

def test_simulate_file_layout(sim_file):
    """Both mcap(+ros2 decoder) and rosbags read every message; counts, times and values agree."""
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory
    from leadscrew_sim.core.params import ScrewParams
    by_topic = {}
    with open(sim_file, 'rb') as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        assert reader.get_header().profile == 'ros2'
        meta = {m.name: dict(m.metadata) for m in reader.iter_metadata()}
        for schema, channel, message, decoded in reader.iter_decoded_messages(
                log_time_order=True):
            assert channel.message_encoding == 'cdr' and schema.encoding == 'ros2msg'
            by_topic.setdefault(channel.topic, []).append((message.log_time, decoded))
        chans = {c.topic: reader.get_summary().schemas[c.schema_id].name
                 for c in reader.get_summary().channels.values()}
    assert chans == {'/torque_command': 'std_msgs/msg/Float64',
                     '/axis/joint_commands': 'sensor_msgs/msg/JointState',
                     '/external_force': 'std_msgs/msg/Float64',
                     '/velocity_command': 'std_msgs/msg/Float64',
                     '/position_command': 'std_msgs/msg/Float64',
                     '/axis/joint_states': 'sensor_msgs/msg/JointState',
                     '/nut_position': 'std_msgs/msg/Float64',
                     '/thread_force': 'geometry_msgs/msg/WrenchStamped',
                     '/sim/joint_states': 'sensor_msgs/msg/JointState',
                     '/sim/thread_state': 'leadscrew_sim/msg/ThreadState',
                     '/sim/ageing': 'leadscrew_sim/msg/AgeingState',
                     '/axis/robot_description': 'std_msgs/msg/String',
                     '/tf_static': 'tf2_msgs/msg/TFMessage',
                     '/tf': 'tf2_msgs/msg/TFMessage'}
    params = meta['leadscrew_sim_parameters']
    assert set(ScrewParams.parameter_names()) <= set(params)
    assert params['clock_mode'] == 'simulate' and params['preset'] == 'tr12x3'
    assert params['update_rate'] == '1000.0' and params['dt_ns'] == '1000000'
    assert 'rosbag2' in meta
    for topic in ('/axis/joint_states', '/nut_position', '/thread_force', '/sim/joint_states',
                  '/torque_command', '/tf'):
        assert len(by_topic[topic]) == 1000, topic
    assert len(by_topic['/axis/robot_description']) == len(by_topic['/tf_static']) == 1
    js = by_topic['/axis/joint_states']
    times = [t for t, _ in js]
    assert times == [k * 1_000_000 for k in range(1, 1001)]
    assert [t for t, _ in by_topic['/torque_command']] == [k * 1_000_000 for k in range(1000)]
    for (t, m), (t2, x) in zip(js, by_topic['/nut_position']):
        assert t == t2 and m.header.stamp.sec * NS + m.header.stamp.nanosec == t
        assert list(m.name) == ['screw_joint', 'nut_joint']
        assert m.position[1] == x.data
    assert any(abs(m.position[1]) > 1e-7 for _, m in js)      # the nut did move

    from rosbags.highlevel import AnyReader
    from pathlib import Path
    n = 0
    with AnyReader([Path(sim_file)]) as r:
        for conn, _t, raw in r.messages():
            r.deserialize(raw, conn.msgtype)
            n += 1
    assert n == 8002      # 8 per tick (command, 6 states, /tf) plus the 2 description messages


# ---------------------------------------------------------------------------
# resim
# ---------------------------------------------------------------------------

def _overall(stdout):
    m = re.search(r'overall max \|diff\|: (\S+)', stdout)
    assert m, stdout
    return float(m.group(1))


def test_resim_bit_identical_and_override(sim_file, tmp_path):
    """Re-simulation without overrides reproduces every state exactly; another backlash differs."""
    out = tmp_path / 'same.mcap'
    r = cli_ok('resim', sim_file, '--output', out)
    assert _overall(r.stdout) == 0.0
    assert 'compared 1000 recorded ticks' in r.stdout
    assert out.is_file()
    # The resim output is itself a recording whose resim is exact.
    r2 = cli_ok('resim', out, '--output', tmp_path / 'again.mcap')
    assert _overall(r2.stdout) == 0.0
    r3 = cli_ok('resim', sim_file, '--set', 'backlash=2e-4', '--output', tmp_path / 'b.mcap')
    assert _overall(r3.stdout) > 0.0


@pytest.mark.parametrize('profile', ['step', 'move'])
def test_simulate_tick_order_with_force_changes(profile, tmp_path):
    """
    Per tick: torque_command at t_k, external_force only when it changes, then the states.

    (axis/robot_description and /tf_static first, /tf after the states, /clock last.)

    2.5 s at 1 kHz spans whole and partial blocks of the batched writer; the
    force CSV changes before the ticks at 0.25 s, 0.999 s (the last tick of
    the first block) and 1.0 s (the first of the second). ``move`` is the closed-loop path. A
    re-simulation of the file reproduces every state exactly.
    """
    from mcap.reader import make_reader
    csv = tmp_path / 'force.csv'
    csv.write_text('time,force\n0,0\n0.2495,3\n0.9985,-2\n0.9995,5\n')
    out = tmp_path / 'run.mcap'
    args = ['--profile', 'step', '--step-time', 0.1, '--amplitude', 0.2] if profile == 'step' \
        else ['--profile', 'move', '--target', 0.002]
    cli_ok('simulate', '--duration', 2.5, *args, '--force-csv', csv, '--clock', '--output', out,
           '--quiet')
    with open(out, 'rb') as f:
        seq = [(c.topic, m.log_time, m.data)
               for _s, c, m in make_reader(f).iter_messages(log_time_order=False)]
    ms = 1_000_000
    forces = [(t, C.decode_float64(d)) for topic, t, d in seq if topic == '/external_force']
    assert forces == [(0, 0.0), (250 * ms, 3.0), (999 * ms, -2.0), (1000 * ms, 5.0)]
    expected = [('/axis/robot_description', 0), ('/tf_static', 0)]
    force_at = {t for t, _ in forces}
    for k in range(2500):
        expected.append(('/torque_command', k * ms))
        if k * ms in force_at:
            expected.append(('/external_force', k * ms))
        expected += [(t, (k + 1) * ms) for t in ('/axis/joint_states', '/nut_position',
                                                 '/thread_force', '/sim/joint_states',
                                                 '/sim/thread_state', '/sim/ageing', '/tf',
                                                 '/clock')]
    assert [(t, lt) for t, lt, _ in seq] == expected
    r = cli_ok('resim', out, '--output', tmp_path / 'again.mcap')
    assert _overall(r.stdout) == 0.0


def test_info(sim_file):
    """Info shows counts, the position range and the stick fraction recorded in the file."""
    r = cli_ok('info', sim_file)
    assert re.search(r'/axis/joint_states\s+sensor_msgs/msg/JointState\s+1000', r.stdout)
    assert 'nut position: min' in r.stdout and 'stuck' in r.stdout
    assert '(recorded in sim/thread_state)' in r.stdout
    assert 'duration:  1.000000 s' in r.stdout


# ---------------------------------------------------------------------------
# play
# ---------------------------------------------------------------------------

def test_play_timing(tmp_path, run_exe):
    """
    A subscriber receives all 200 axis/joint_states of a 100 Hz file in order, with their spacing.

    Tolerance: median |inter-arrival - 10 ms| < 2 ms. The player sleeps to
    absolute deadlines (sub-0.1 ms wake-up error); local DDS delivery and the
    Python executor of this test add ~0.1-1 ms of jitter on a loaded machine,
    while a player that ignored the timing (bursts) or scaled it wrongly would
    be off by ~10 ms.
    """
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.qos import QoSProfile, ReliabilityPolicy
    from sensor_msgs.msg import JointState
    path = tmp_path / 'p.mcap'
    cli_ok('simulate', '--update-rate', 100, '--duration', 2.0, '--torque', 0.0, '--output', path,
           '-q')
    ctx = rclpy.Context()
    rclpy.init(context=ctx)
    node = rclpy.create_node('play_listener', context=ctx)
    got = []
    node.create_subscription(
        JointState, '/axis/joint_states',
        lambda m: got.append((time.monotonic(), m.header.stamp.sec * NS + m.header.stamp.nanosec)),
        QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE))
    ex = SingleThreadedExecutor(context=ctx)
    ex.add_node(node)
    th = threading.Thread(target=ex.spin, daemon=True)
    th.start()
    try:
        p = run_exe('leadscrew_sim.cli', 'play', path, '--topics', '/axis/joint_states',
                    '--wait-subscribers', 1, '--wait-timeout', 10)
        assert p.wait(timeout=30) == 0, p.output()
        end = time.monotonic() + 5
        while len(got) < 200 and time.monotonic() < end:
            time.sleep(0.05)
    finally:
        ex.shutdown()
        node.destroy_node()
        rclpy.shutdown(context=ctx)
    assert [s for _, s in got] == [k * 10_000_000 for k in range(1, 201)]
    gaps = [b[0] - a[0] for a, b in zip(got, got[1:])]
    errs = sorted(abs(g - 0.010) for g in gaps)
    assert errs[len(errs) // 2] < 0.002, errs[len(errs) // 2]
    assert abs((got[-1][0] - got[0][0]) - 1.99) < 0.1


# ---------------------------------------------------------------------------
# plot
# ---------------------------------------------------------------------------

def test_plot_png(tmp_path):
    """A stick-slip move gives a 1200x900 PNG."""
    path = tmp_path / 'ss.mcap'
    cli_ok('simulate', '--preset', 'stick_slip', '--profile', 'move', '--target', 0.004,
           '--speed', 0.002, '--duration', 3.0, '--output', path, '-q')
    png = tmp_path / 'ss.png'
    cli_ok('plot', path, '--output', png)
    data = png.read_bytes()
    assert data[:8] == b'\x89PNG\r\n\x1a\n'
    assert data[12:16] == b'IHDR'
    assert struct.unpack('>II', data[16:24]) == (1200, 900)


# ---------------------------------------------------------------------------
# bad input
# ---------------------------------------------------------------------------

def _non_ros_mcap(path):
    from mcap.writer import Writer
    with open(path, 'wb') as f:
        w = Writer(f)
        w.start(profile='', library='test')
        sid = w.register_schema('Point', 'jsonschema', b'{"type": "object"}')
        cid = w.register_channel('/points', 'json', sid)
        for i in range(10):
            w.add_message(cid, i * 1000, b'{"x": %d}' % i, i * 1000)
        w.finish()


def _bad_cases(tmp, sim_file):
    data = sim_file.read_bytes()
    (tmp / 'half.mcap').write_bytes(data[:len(data) // 2])
    corrupt = bytearray(data)
    rng = random.Random(3)
    for i in range(len(data) // 4, len(data) // 2):
        corrupt[i] = rng.randrange(256)
    (tmp / 'corrupt.mcap').write_bytes(bytes(corrupt))
    (tmp / 'noise.mcap').write_bytes(bytes(rng.randrange(256) for _ in range(5000)))
    _non_ros_mcap(tmp / 'json.mcap')
    (tmp / 'bad.csv').write_text('time,torque\n0.0,0.1\n0.5,abc\n')
    return {
        'missing': (['info', tmp / 'nope.mcap'], 'no such file'),
        'truncated': (['info', tmp / 'half.mcap'], 'truncated or corrupt'),
        'truncated_resim': (['resim', tmp / 'half.mcap'], 'truncated or corrupt'),
        'corrupt': (['resim', tmp / 'corrupt.mcap'], 'corrupt'),
        'noise': (['info', tmp / 'noise.mcap'], 'not an MCAP file'),
        'non_ros_info': (['info', tmp / 'json.mcap'], 'not a ROS 2 recording'),
        'non_ros_resim': (['resim', tmp / 'json.mcap'], 'not a ROS 2 recording'),
        'non_ros_play': (['play', tmp / 'json.mcap'], 'not a ROS 2 recording'),
        'csv': (['simulate', '--torque-csv', tmp / 'bad.csv', '--duration', 0.1,
                 '-o', tmp / 'x.mcap'], 'line 3'),
        'unknown_set': (['simulate', '--set', 'bogus_key=1', '--duration', 0.1,
                         '-o', tmp / 'y.mcap'], 'bogus_key'),
        'bad_set_value': (['simulate', '--set', 'backlash=-1', '--duration', 0.1,
                           '-o', tmp / 'z.mcap'], 'backlash'),
        'usage': (['simulate', '--duration', 'abc'], 'invalid float'),
    }


def test_bad_input(sim_file, tmp_path):
    """Each bad input: non-zero exit, exactly one stderr line containing 'error', no traceback."""
    for name, (args, needle) in _bad_cases(tmp_path, sim_file).items():
        r = cli(*args)
        lines = r.stderr.strip().splitlines()
        assert r.returncode != 0, name
        assert 'Traceback' not in r.stderr, (name, r.stderr)
        assert len(lines) == 1, (name, r.stderr)
        assert 'error' in lines[0] and needle in lines[0], (name, lines[0])
