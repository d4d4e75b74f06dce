"""
Recordings made by the running node, read back by independent readers.

The node runs as a real process on the test session's isolated DDS domain
(set up by conftest.py); a live subscriber in the test process sees what the node
published. Each recording is read with mcap + mcap_ros2 and with rosbags and
compared with the live data: a clean stop (SIGINT, SIGTERM), a crash
(SIGKILL, then ``leadscrew_sim.io.session.recover``), a lockstep run that
``leadscrew_sim resim`` reproduces bit for bit, and ``leadscrew_sim play``.
"""
import math
import os
from pathlib import Path
import re
import signal
import struct
import subprocess
import sys
import time

from helpers import cli_ok, MS, NODE, NodeProcess, NS, Ros, SHARED, stamp_ns, wait_states
from leadscrew_sim.core import load_preset, ScrewParams
from leadscrew_sim.io.msgdefs import ros2msg_definition
from leadscrew_sim.io.session import recover
from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory
import pytest
from rclpy.qos import QoSProfile, ReliabilityPolicy
from rosbags.highlevel import AnyReader
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64
from std_srvs.srv import Trigger

#: The mcap CLI, an independent reader and checker (absent in a user's clone).
MCAP_CLI = SHARED / 'mcap-cli' / 'mcap'

#: QoS of the axis/joint_states subscriptions of this module (deeper than helpers.DEEP).
DEEP = QoSProfile(depth=5000, reliability=ReliabilityPolicy.RELIABLE)

#: Recorded topics of a realtime run -> message type.
TYPES = {
    '/torque_command': 'std_msgs/msg/Float64',
    '/axis/joint_commands': 'sensor_msgs/msg/JointState',
    '/external_force': 'std_msgs/msg/Float64',
    '/axis/joint_states': 'sensor_msgs/msg/JointState',
    '/nut_position': 'std_msgs/msg/Float64',
    '/thread_force': 'geometry_msgs/msg/WrenchStamped',
    '/sim/joint_states': 'sensor_msgs/msg/JointState',
    '/sim/thread_state': 'leadscrew_sim/msg/ThreadState',
    '/sim/ageing': 'leadscrew_sim/msg/AgeingState',
    '/diagnostics': 'diagnostic_msgs/msg/DiagnosticArray',
    '/velocity_command': 'std_msgs/msg/Float64',
    '/position_command': 'std_msgs/msg/Float64',
    '/limit_switch/min': 'std_msgs/msg/Bool',
    '/limit_switch/max': 'std_msgs/msg/Bool',
    '/home_switch': 'std_msgs/msg/Bool',
    '/axis/robot_description': 'std_msgs/msg/String',
    '/tf_static': 'tf2_msgs/msg/TFMessage',
    '/tf': 'tf2_msgs/msg/TFMessage',
}

#: The topics the realtime run sends or publishes messages on (no velocity or position command).
SENT_TYPES = {t: v for t, v in TYPES.items()
              if t not in ('/velocity_command', '/position_command')}

#: Flush interval of the crash test [s]: the recorder child writes out the open
#: chunk at least this often (checked on each write).
FLUSH = 0.5
#: Allowed on top of FLUSH [s]: a message reaches the file through the node's
#: per-tick pipe write and the recorder child's read loop (a child process
#: that the scheduler of 2 shared cores may hold back, and that stalls
#: 10-15 ms while it compresses a chunk), and the flush is only checked when
#: the child writes. The measured loss is printed.
MARGIN = 0.5


def js_key(msg):
    """Return (stamp, names, position, velocity, effort) of any decoded JointState."""
    return (stamp_ns(msg), tuple(msg.name), tuple(float(v) for v in msg.position),
            tuple(float(v) for v in msg.velocity), tuple(float(v) for v in msg.effort))


def bits(values):
    """Return the IEEE 754 bit patterns of doubles (tells -0.0 from +0.0)."""
    return tuple(struct.pack('<d', v) for v in values)


class Live(Ros):
    """The helpers.Ros helper plus axis/joint_states capture with receive times."""

    def states(self):
        """Subscribe to axis/joint_states; return the list of (receive time.time_ns(), msg)."""
        out = []
        self.node.create_subscription(JointState, 'axis/joint_states',
                                      lambda m: out.append((time.time_ns(), m)), DEEP)
        return out

    def publisher(self, msg_type, topic, timeout=30.0):
        """Create a publisher and wait until the node subscribed to it."""
        pub = self.node.create_publisher(msg_type, topic, 10)
        assert self.spin_until(lambda: pub.get_subscription_count() > 0, timeout), topic
        return pub


@pytest.fixture
def live():
    """Yield a Live helper."""
    r = Live()
    yield r
    r.close()


def node_argv(directory, prefix, *params):
    """Return the argv of a recording node writing <directory>/<prefix>_*.mcap."""
    argv = [sys.executable, '-m', 'leadscrew_sim.node', '--ros-args',
            '-p', f'record_dir:={directory}', '-p', f'record_prefix:={prefix}']
    for p in params:
        argv += ['-p', p]
    return argv


def log_text(proc):
    """Return what a (possibly stopped) NodeProcess printed."""
    return Path(proc.log_path).read_text(errors='replace')


def only_file(directory, prefix):
    """Return the single recording <prefix>_*.mcap in directory."""
    files = sorted(Path(directory).glob(f'{prefix}_*.mcap'))
    assert len(files) == 1, files
    return files[0]


def read_mcap(path):
    """Return ([(topic, schema name, log_time, decoded)], summary, metadata) via mcap_ros2."""
    with open(path, 'rb') as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        msgs = [(c.topic, s.name, m.log_time, d) for s, c, m, d in
                reader.iter_decoded_messages(log_time_order=False)]
        summary = reader.get_summary()
        meta = {m.name: dict(m.metadata) for m in reader.iter_metadata()}
    return msgs, summary, meta


def read_rosbags(path):
    """Return [(topic, msgtype, log_time, decoded)] via rosbags' AnyReader."""
    with AnyReader([Path(path)]) as reader:
        return [(c.topic, c.msgtype, t, reader.deserialize(raw, c.msgtype))
                for c, t, raw in reader.messages()]


def raw_messages(path, topic):
    """Return [(log_time, bytes)] of one topic in file order."""
    with open(path, 'rb') as f:
        return [(m.log_time, m.data) for _s, _c, m in
                make_reader(f).iter_messages(topics=[topic], log_time_order=False)]


def check_complete(path, expected_messages=None):
    """Assert a summary whose statistics count every message; return the count."""
    with open(path, 'rb') as f:
        reader = make_reader(f)
        summary = reader.get_summary()
        assert summary is not None, f'{path}: no summary (file not closed)'
        n = sum(1 for _ in reader.iter_messages(log_time_order=False))
    st = summary.statistics
    assert st.message_count == n == sum(st.channel_message_counts.values())
    if expected_messages is not None:
        assert n == expected_messages
    return n


# ---------------------------------------------------------------------------
# A realtime recording, shared by the read-back and play tests
# ---------------------------------------------------------------------------

@pytest.fixture(scope='module')
def realtime_run(tmp_path_factory):
    """
    Run the node in realtime mode for ~2 s with commands, stop it with SIGINT.

    Returns dict(path, states (live axis/joint_states), sent {topic: [values]}, log).
    """
    tmp = tmp_path_factory.mktemp('realtime')
    # the torques run the axis past the preset's overspeed trip: off here (max_screw_velocity 0)
    proc = NodeProcess(node_argv(tmp, 'rt', 'max_screw_velocity:=0.0'), tmp / 'node.log')
    lv = Live()
    try:
        states = lv.states()
        wait_states(lv, states, proc)
        pub_t = lv.publisher(Float64, 'torque_command')
        pub_j = lv.publisher(JointState, 'axis/joint_commands')
        pub_f = lv.publisher(Float64, 'external_force')
        sent = {'/torque_command': [], '/axis/joint_commands': [], '/external_force': []}
        for k in range(40):
            if k % 10 == 5:
                value = -0.011 * k
                pub_j.publish(JointState(name=['screw_joint'], effort=[value]))
                sent['/axis/joint_commands'].append((('screw_joint',), (value,)))
            else:
                value = 0.2 * math.sin(k / 4.0) + 1e-9 * k      # all distinct
                pub_t.publish(Float64(data=value))
                sent['/torque_command'].append(value)
            if k % 13 == 0:
                pub_f.publish(Float64(data=2.5 * k))
                sent['/external_force'].append(2.5 * k)
            lv.spin_for(0.05)
        lv.spin_for(0.2)
        n = len(states)
        rc = proc.stop(signal.SIGINT, timeout=30.0)
        lv.spin_for(0.2)
        assert rc == 0, proc.output()
        assert len(states) >= n
        return dict(path=only_file(tmp, 'rt'), states=[m for _t, m in states], sent=sent,
                    log=log_text(proc))
    finally:
        proc.stop(signal.SIGKILL)
        lv.close()


@pytest.mark.timeout(120)
def test_realtime_recording_read_back_by_mcap_and_rosbags(realtime_run):
    path, sent = realtime_run['path'], realtime_run['sent']
    live = {js_key(m)[0]: js_key(m) for m in realtime_run['states']}
    assert len(live) > 1000, len(live)
    msgs, summary, meta = read_mcap(path)

    # The file was closed on SIGINT: summary, statistics, the rosbag2 record.
    assert summary is not None
    assert summary.statistics.message_count == len(msgs)
    assert 'rosbag2' in meta and f'{len(msgs)} messages' in realtime_run['log']
    # Every message decoded; one schema per type, channels with the right types.
    assert {t: s for t, s, _, _ in msgs} == SENT_TYPES
    assert {c.topic: summary.schemas[c.schema_id].name
            for c in summary.channels.values()} == TYPES
    assert all(d is not None for *_x, d in msgs)
    # The schema texts are the installed .msg files with their dependencies.
    for schema in summary.schemas.values():
        assert schema.encoding == 'ros2msg'
        assert schema.data.decode() == ros2msg_definition(schema.name), schema.name

    # The parameters record holds every physics parameter, with the preset's values.
    params = meta['leadscrew_sim_parameters']
    preset = load_preset('tr12x3', max_screw_velocity=0.0)     # and the run's override
    for name, public in zip(ScrewParams.names(), ScrewParams.parameter_names()):
        assert params[public] == str(getattr(preset, name)), public
    assert params['clock_mode'] == 'realtime' and params['dt_ns'] == str(MS)
    t0 = int(params['t0_ns'])

    # axis/joint_states: on the dt grid from t0, log time = header stamp, no gap,
    # and equal to what the live subscriber received.
    rec = [(lt, js_key(d)) for t, _s, lt, d in msgs if t == '/axis/joint_states']
    assert all(lt == key[0] and (lt - t0) % MS == 0 for lt, key in rec)
    stamps = [key[0] for _lt, key in rec]
    assert {b - a for a, b in zip(stamps, stamps[1:])} == {MS}
    recorded = {key[0]: key for _lt, key in rec}
    assert set(live) <= set(recorded)
    assert all(recorded[s] == live[s] for s in live)
    assert all(bits(recorded[s][4]) == bits(live[s][4]) for s in live)
    assert recorded[stamps[0]][1] == ('screw_joint', 'nut_joint')

    # Commands: exactly as sent, in order, logged on the tick grid.
    cmds = {t: [(lt, d) for tt, _s, lt, d in msgs if tt == t] for t in sent}
    assert [d.data for _lt, d in cmds['/torque_command']] == sent['/torque_command']
    assert [d.data for _lt, d in cmds['/external_force']] == sent['/external_force']
    assert [(tuple(d.name), tuple(d.effort)) for _lt, d in cmds['/axis/joint_commands']] == \
        sent['/axis/joint_commands']
    assert all((lt - t0) % MS == 0 for c in cmds.values() for lt, _d in c)
    # A torque command logged at t acts on the step [t, t + dt): the state stamped
    # t + dt reports it as the motor torque (torque_lag 0, below max_torque).
    torque_cmds = [(lt, d.data) for lt, d in cmds['/torque_command']] + \
        [(lt, d.effort[0]) for lt, d in cmds['/axis/joint_commands']]
    times = [lt for lt, _v in torque_cmds]
    checked = 0
    for lt, value in torque_cmds:
        if times.count(lt) == 1 and lt + MS in recorded:
            assert recorded[lt + MS][4][0] == value, (lt, value)
            checked += 1
    assert checked >= len(torque_cmds) - 3, (checked, len(torque_cmds))

    # rosbags reads the same messages with the same types and values.
    bag = read_rosbags(path)
    assert sorted((t, lt) for t, _ty, lt, _d in bag) == sorted(
        (t, lt) for t, _s, lt, _d in msgs)
    assert {t: ty for t, ty, _lt, _d in bag} == SENT_TYPES
    bag_js = {js_key(d)[0]: js_key(d) for t, _ty, _lt, d in bag if t == '/axis/joint_states'}
    assert bag_js == recorded
    bag_tq = [d.data for t, _ty, _lt, d in bag if t == '/torque_command']
    assert bag_tq == sent['/torque_command']


@pytest.mark.timeout(90)
def test_play_node_recording_delivers_every_joint_state_in_order(realtime_run, live):
    path = realtime_run['path']
    expected = [js_key(d) for t, _s, _lt, d in read_mcap(path)[0] if t == '/axis/joint_states']
    got = []
    live.node.create_subscription(JointState, 'axis/joint_states', lambda m: got.append(js_key(m)),
                                  DEEP)
    log = open(Path(path).with_suffix('.play.log'), 'w')
    player = subprocess.Popen(
        [sys.executable, '-m', 'leadscrew_sim.cli', 'play', str(path),
         '--wait-subscribers', '1', '--wait-timeout', '30'],
        stdout=log, stderr=subprocess.STDOUT, env=dict(os.environ))
    try:
        live.spin_until(lambda: player.poll() is not None, 60.0)
        live.spin_until(lambda: len(got) >= len(expected), 5.0)
    finally:
        if player.poll() is None:
            player.kill()
        player.wait(timeout=10)
        log.close()
    out = Path(log.name).read_text()
    assert player.returncode == 0, out
    print(out.strip())
    assert len(got) == len(expected), (len(got), len(expected), out)
    assert got == expected


# ---------------------------------------------------------------------------
# Stops: SIGTERM, SIGKILL
# ---------------------------------------------------------------------------

@pytest.mark.timeout(90)
def test_sigterm_closes_the_recording(live, tmp_path):
    proc = NodeProcess(node_argv(tmp_path, 'term'), tmp_path / 'node.log')
    try:
        states = live.states()
        wait_states(live, states, proc, n=500)
        proc.send(signal.SIGTERM)
        assert proc.wait(timeout=30) == 0, proc.output()
    finally:
        proc.stop(signal.SIGKILL)
    path = only_file(tmp_path, 'term')
    n = check_complete(path)
    assert f'({path.stat().st_size} B, {n} messages)' in log_text(proc), log_text(proc)
    recorded = {js_key(d)[0]: js_key(d) for t, _s, _lt, d in read_mcap(path)[0]
                if t == '/axis/joint_states'}
    got = {js_key(m)[0]: js_key(m) for _t, m in states}
    assert set(got) <= set(recorded)
    assert all(recorded[s] == got[s] for s in got)


def _kill_run(live, tmp_path, seconds, group):
    """Record for ``seconds``, SIGKILL the node (group: and its recorder child)."""
    proc = NodeProcess(node_argv(tmp_path, 'kill', f'record_flush_interval:={FLUSH}'),
                       tmp_path / 'node.log')
    try:
        states = live.states()
        wait_states(live, states, proc)
        live.spin_for(seconds)
        kill_wall = time.time_ns()
        if group:
            os.killpg(proc.proc.pid, signal.SIGKILL)
        else:
            proc.send(signal.SIGKILL)
        assert proc.wait(timeout=10) == -signal.SIGKILL
    finally:
        proc.stop(signal.SIGKILL)
    # The node's sim time runs behind the wall clock by its start-up (and any
    # skipped steps): map the kill into log time with the smallest receive
    # delay of the live subscriber (an upper bound of the offset by the DDS latency).
    offset = min(t - stamp_ns(m) for t, m in states)
    live_js = {js_key(m)[0]: js_key(m) for _t, m in states}
    return only_file(tmp_path, 'kill'), kill_wall - offset, live_js


@pytest.mark.timeout(90)
def test_sigkill_of_node_and_recorder_recover_within_flush_bound(live, tmp_path):
    path, kill_log, live_js = _kill_run(live, tmp_path, 6.0, group=True)
    with open(path, 'rb') as f:
        try:
            complete = make_reader(f).get_summary() is not None
        except Exception:  # noqa: B902 - a truncated file may raise anything
            complete = False
    assert not complete, 'the killed recorder cannot have written a summary'
    fixed = tmp_path / 'fixed.mcap'
    n = len(recover(path, fixed).messages)
    check_complete(fixed, n)
    msgs, _summary, meta = read_mcap(fixed)
    assert 'leadscrew_sim_parameters' in meta
    rec = {js_key(d)[0]: js_key(d) for t, _s, _lt, d in msgs if t == '/axis/joint_states'}
    stamps = sorted(rec)
    bound = kill_log - int((FLUSH + MARGIN) * NS)
    lost = (kill_log - stamps[-1]) / NS
    print(f'recovered {n} messages, joint_states up to {lost:.3f} s before the kill '
          f'(bound {FLUSH} + {MARGIN} s)')
    assert stamps[-1] >= bound, lost
    # Every step up to the bound is there, and equals what the live subscriber got.
    assert {b - a for a, b in zip(stamps, stamps[1:])} == {MS}
    assert {s for s in live_js if s < bound} <= set(rec)
    assert all(rec[s] == live_js[s] for s in live_js if s in rec)
    # The verb writes the same repair, and says what it saved and where the file stops.
    verb = tmp_path / 'verb.mcap'
    r = cli_ok('recover', path, '-o', verb)
    assert f'{n} messages' in r.stdout and 'stops being whole at byte' in r.stdout, r.stdout
    assert [m[:3] for m in read_mcap(verb)[0]] == [m[:3] for m in msgs]
    with AnyReader([verb]) as reader:            # an independent reader takes the copy
        assert sum(1 for c in reader.connections if c.topic == '/axis/joint_states') == 1
        assert sum(1 for _ in reader.messages()) == n
    # info and resim read the cut file itself up to its last whole chunk, with a warning.
    for verb_args in (('info', path), ('resim', path, '-q', '-o', tmp_path / 'cut.resim.mcap')):
        r = cli_ok(*verb_args)
        warn = [line for line in r.stderr.splitlines() if 'warning' in line]
        assert len(warn) == 1 and 'recover' in warn[0], r.stderr
    if MCAP_CLI.exists():
        doc = subprocess.run([str(MCAP_CLI), 'doctor', str(verb)], capture_output=True,
                             text=True, timeout=60)
        assert doc.returncode == 0, doc.stdout + doc.stderr
        # The independent tool recovers the same file into one its own doctor accepts,
        # with the same axis/joint_states (its order of records is its own).
        go = tmp_path / 'go.mcap'
        r = subprocess.run([str(MCAP_CLI), 'recover', str(path), '-o', str(go)],
                           capture_output=True, text=True, timeout=60)
        assert r.returncode == 0, r.stderr
        doc = subprocess.run([str(MCAP_CLI), 'doctor', str(go)], capture_output=True,
                             text=True, timeout=60)
        assert doc.returncode == 0, doc.stdout + doc.stderr
        go_js = {js_key(d)[0] for t, _s, _lt, d in read_mcap(go)[0] if t == '/axis/joint_states'}
        assert go_js == set(rec)


@pytest.mark.skipif(not MCAP_CLI.exists(), reason='the mcap CLI (../shared) is absent')
def test_node_recording_chunks_do_not_overlap(realtime_run):
    """``mcap info`` finds no overlapping chunks and ``mcap doctor`` no error in a node file."""
    path = str(realtime_run['path'])
    info = subprocess.run([str(MCAP_CLI), 'info', path], capture_output=True, text=True,
                          timeout=60)
    assert info.returncode == 0, info.stderr
    assert re.search(r'overlaps: no\b', info.stdout), info.stdout
    doc = subprocess.run([str(MCAP_CLI), 'doctor', path], capture_output=True, text=True,
                         timeout=60)
    assert doc.returncode == 0, doc.stdout + doc.stderr


@pytest.mark.timeout(90)
def test_sigkill_of_node_alone_leaves_a_closed_file(live, tmp_path):
    path, kill_log, live_js = _kill_run(live, tmp_path, 2.0, group=False)
    # The recorder child sees EOF on its pipe and closes the file itself.
    end = time.monotonic() + 20.0
    while True:
        try:
            n = check_complete(path)
            break
        except Exception:  # noqa: B902 - not closed yet
            if time.monotonic() > end:
                raise
            time.sleep(0.1)
    rec = {js_key(d)[0]: js_key(d) for t, _s, _lt, d in read_mcap(path)[0]
           if t == '/axis/joint_states'}
    # Only what the node had not yet written to the pipe is lost (a tick or so).
    bound = kill_log - int(0.1 * NS)
    print(f'{n} messages; joint_states up to {(kill_log - max(rec)) / NS:.3f} s '
          'before the kill')
    assert max(rec) >= bound
    assert {s for s in live_js if s < bound} <= set(rec)
    assert all(rec[s] == live_js[s] for s in live_js if s in rec)
    # the recorder child, left alone, finishes the file without a traceback
    assert 'Traceback' not in (tmp_path / 'node.log').read_text()


# ---------------------------------------------------------------------------
# Lockstep: resim reproduces the node bit for bit
# ---------------------------------------------------------------------------

def _resim_rows(stdout):
    """Return {(topic, field): (max |diff|, n)} and the overall line of resim's output."""
    rows = {}
    for line in stdout.splitlines():
        m = re.match(r'^(/\S+)\s+(\S+)\s+(\S+)\s+(\S+)\s+(\d+)', line)
        if m:
            rows[(m.group(1), m.group(2))] = (float(m.group(3)), int(m.group(5)))
    overall = re.search(r'compared (\d+) recorded ticks; overall max \|diff\|: (\S+)', stdout)
    assert rows and overall, stdout
    return rows, int(overall.group(1)), float(overall.group(2))


def lockstep_commands(n):
    """Return n torque commands: reversals, holds at 0.0 and -0.0, all finite."""
    out = []
    for k in range(n):
        if 100 <= k < 110:
            out.append(-0.0 if k % 2 else 0.0)
        else:
            out.append(0.3 * math.sin(k / 15.0) + (0.2 if (k // 40) % 2 else -0.15))
    return out


@pytest.mark.timeout(150)
def test_lockstep_recording_resim_is_bit_identical(live, tmp_path):
    commands = lockstep_commands(300)
    # the torques run the axis past the preset's overspeed trip: off here (max_screw_velocity 0)
    proc = NodeProcess(node_argv(tmp_path, 'ls', 'clock_mode:=lockstep', 'preset:=stick_slip',
                                 'max_screw_velocity:=0.0'), tmp_path / 'node.log')
    try:
        states = live.states()
        pub = live.publisher(Float64, 'torque_command')
        fpub = live.publisher(Float64, 'external_force')
        assert live.spin_until(lambda: live.node.count_publishers('/axis/joint_states') > 0, 10.0)
        for k, torque in enumerate(commands):
            if k in (50, 200):
                fpub.publish(Float64(data=-40.0 if k == 50 else 0.0))
                live.spin_for(0.05)
            if k == 150:
                res = live.node.create_client(Trigger, f'{NODE}/reset')
                assert live.spin_until(res.service_is_ready, 10.0)
                fut = res.call_async(Trigger.Request())
                assert live.spin_until(fut.done, 10.0) and fut.result().success
            pub.publish(Float64(data=torque))
            assert live.spin_until(lambda: len(states) > k, 10.0), (k, proc.output())
        live.spin_for(0.2)
        assert len(states) == len(commands)
        assert proc.stop(signal.SIGINT, timeout=30.0) == 0, proc.output()
    finally:
        proc.stop(signal.SIGKILL)
    path = only_file(tmp_path, 'ls')
    check_complete(path)
    live_js = [js_key(m) for _t, m in states]
    assert [s[0] for s in live_js] == [(k + 1) * MS for k in range(len(commands))]
    recorded = [js_key(d) for t, _s, _lt, d in read_mcap(path)[0] if t == '/axis/joint_states']
    assert recorded == live_js
    # The recorded efforts are the commands, bit for bit (+0.0 for -0.0: the node
    # normalizes the sign of a zero motor torque).
    assert [bits(s[4][:1])[0] for s in live_js] == [
        struct.pack('<d', c + 0.0) for c in commands]

    out = tmp_path / 'ls.resim.mcap'
    r = cli_ok('resim', path, '--output', out, '--quiet')
    print(r.stdout)
    rows, compared, overall = _resim_rows(r.stdout)
    assert compared == len(commands)
    assert len(rows) == 9 + 9      # 9 fields of the sensor topics, 9 of sim/joint_states
    assert all(mx == 0.0 and n == len(commands) for mx, n in rows.values()), rows
    assert overall == 0.0 and '(bit-identical)' in r.stdout
    # Independently of resim's own report: the states it wrote are the node's bytes.
    for topic in ('/axis/joint_states', '/nut_position', '/thread_force', '/sim/joint_states'):
        assert raw_messages(out, topic) == raw_messages(path, topic), topic

    r = cli_ok('resim', path, '--set', 'backlash=2e-4', '--output', tmp_path / 'b.mcap',
               '--quiet')
    rows, compared, overall = _resim_rows(r.stdout)
    assert compared == len(commands)
    assert overall > 0.0 and '(bit-identical)' not in r.stdout
    assert rows[('/axis/joint_states', 'position[nut_joint]')][0] > 0.0


def _aging_torque_run(live, tmp_path, prefix, timeout, on_tick=None):
    """
    Run a lockstep node: three 0.3 N m torque commands, then ticks that let it age.

    ``timeout`` is the start-up command_timeout [s]; ``on_tick(k)`` runs before
    tick k. Returns the applied efforts of the 13 states and resim's overall diff.
    """
    proc = NodeProcess(node_argv(tmp_path, prefix, 'clock_mode:=lockstep',
                                 f'command_timeout:={timeout}'), tmp_path / 'node.log')
    try:
        states = live.states()
        pub = live.publisher(Float64, 'torque_command')
        jpub = live.publisher(JointState, 'axis/joint_commands')
        for k in range(13):
            if on_tick is not None:
                on_tick(k)
            if k < 3:
                pub.publish(Float64(data=0.3))
            else:
                jpub.publish(JointState(name=['other_joint'], effort=[0.0]))
            assert live.spin_until(lambda: len(states) > k, 10.0), (k, log_text(proc))
        assert proc.stop(signal.SIGINT, timeout=30.0) == 0, log_text(proc)
    finally:
        proc.stop(signal.SIGKILL)
    r = cli_ok('resim', only_file(tmp_path, prefix), '--output', tmp_path / 'r.mcap',
               '--quiet')
    return [m.effort[0] for _t, m in states], _resim_rows(r.stdout)[2]


@pytest.mark.timeout(150)
def test_lockstep_command_timeout_resim_matches_node(live, tmp_path):
    efforts, resim_diff = _aging_torque_run(live, tmp_path, 'age', 0.005)
    # Command logged at 2 ms, timeout 5 ms: the step from 8 ms (age 6 ms) gets 0.
    assert efforts == [0.3] * 8 + [0.0] * 5, efforts
    assert resim_diff == 0.0


@pytest.mark.timeout(150)
def test_a_run_time_setting_change_is_recorded_and_resim_applies_it(live, tmp_path):
    from helpers import NODE, param_msg
    from rcl_interfaces.srv import SetParameters

    def set_timeout(k):
        if k == 4:     # from now on a command older than 5 ms times out
            res = live.call(SetParameters, f'{NODE}/set_parameters', SetParameters.Request(
                parameters=[param_msg('command_timeout', 0.005)]))
            assert res.results[0].successful, res.results[0].reason
    efforts, resim_diff = _aging_torque_run(live, tmp_path, 'set', 0.0, set_timeout)
    # The same ages as with the timeout set from the start: 0 N m from the step at 8 ms.
    assert efforts == [0.3] * 8 + [0.0] * 5, efforts
    # resim knows the timeout only from the recorded change (it starts with 0: none).
    assert resim_diff == 0.0
