"""MCAP recording: files read back by mcap + mcap_ros2 and by rosbags, crash recovery."""
import os
from pathlib import Path
import re
import signal
import subprocess
import sys
import textwrap
import time

from ament_index_python.packages import get_package_share_directory
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import Vector3, Wrench, WrenchStamped
from helpers import REPO
from leadscrew_sim.io.msgdefs import cdr_length, ros2msg_definition
from leadscrew_sim.io.mcap_file import McapRecorder
from leadscrew_sim.io.session import recover, RecordingSession, StorageOptions
from mcap.reader import make_reader
from mcap.stream_reader import StreamReader
from mcap_ros2.decoder import DecoderFactory
import pytest
from rclpy.serialization import deserialize_message, serialize_message
from rosbags.highlevel import AnyReader
from rosbags.typesys import get_typestore, Stores
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64, Header, String
import yaml

FLUSH = 0.2          # s, flush interval of the crash tests
MARGIN = 0.3         # s, allowed on top of FLUSH for the write period and scheduling
SEP = '=' * 80


def _msgs(i):
    """Return four messages whose values all depend on i, with their topics."""
    stamp = Header(frame_id=f'f{i}')
    stamp.stamp.sec, stamp.stamp.nanosec = i, 1000 * i
    return [
        ('/joint_states', 'sensor_msgs/msg/JointState',
         JointState(header=stamp, name=['screw', 'nut'], position=[0.5 * i, -1.0 * i],
                    velocity=[float(i)], effort=[])),
        ('/nut/position', 'std_msgs/msg/Float64', Float64(data=i / 7.0)),
        ('/wrench', 'geometry_msgs/msg/WrenchStamped',
         WrenchStamped(header=stamp, wrench=Wrench(force=Vector3(x=1.0 * i, z=-2.0),
                                                   torque=Vector3(y=0.25 * i)))),
        ('/diagnostics', 'diagnostic_msgs/msg/DiagnosticArray',
         DiagnosticArray(header=stamp, status=[DiagnosticStatus(
             level=bytes([i % 3]), name=f'axis{i}', message='ok',
             values=[KeyValue(key='k', value=str(i))] * (i % 3))])),
    ]


def _check_values(topic, msg, i):
    """Assert that msg (rclpy, mcap_ros2 or rosbags object) carries the values of _msgs(i)."""
    if topic == '/joint_states':
        assert list(msg.name) == ['screw', 'nut']
        assert list(msg.position) == [0.5 * i, -1.0 * i]
        assert list(msg.velocity) == [float(i)] and len(msg.effort) == 0
        assert msg.header.frame_id == f'f{i}' and msg.header.stamp.nanosec == 1000 * i
    elif topic == '/nut/position':
        assert msg.data == i / 7.0
    elif topic == '/wrench':
        assert (msg.wrench.force.x, msg.wrench.force.z) == (1.0 * i, -2.0)
        assert msg.wrench.torque.y == 0.25 * i and msg.header.stamp.sec == i
    else:
        (status,) = msg.status
        level = status.level if isinstance(status.level, int) else status.level[0]
        assert level == i % 3 and status.name == f'axis{i}'
        assert [(kv.key, kv.value) for kv in status.values] == [('k', str(i))] * (i % 3)


def _read_mcap(path):
    """Return [(topic, schema name, log_time, decoded)] and the summary, via mcap_ros2."""
    with open(path, 'rb') as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        out = [(c.topic, s.name, m.log_time, d) for s, c, m, d in reader.iter_decoded_messages()]
        return out, reader.get_summary(), {m.name: m.metadata for m in reader.iter_metadata()}


def _read_rosbags(path):
    """Return [(topic, msgtype, log_time, decoded)] via rosbags' AnyReader on a bare .mcap."""
    with AnyReader([Path(path)]) as reader:
        return [(c.topic, c.msgtype, t, reader.deserialize(raw, c.msgtype))
                for c, t, raw in reader.messages()]


def _complete(path):
    """Return True if path has a summary that mcap's seeking reader accepts."""
    try:
        with open(path, 'rb') as f:
            return make_reader(f).get_summary() is not None
    except Exception:  # noqa: B902 - any failure means: not a complete file
        return False


def test_roundtrip_four_types_both_readers(tmp_path):
    path = tmp_path / 'four.mcap'
    rec = McapRecorder(path, flush_interval=0.05, chunk_size=4096)
    ids = {}
    expected = []
    for i in range(60):
        for topic, msg_type, msg in _msgs(i):
            if topic not in ids:
                ids[topic] = rec.add_channel(topic, msg_type)
            t = 1_700_000_000_000_000_000 + 1_000_000 * len(expected)
            rec.write(ids[topic], serialize_message(msg), t, publish_time_ns=t - 5)
            expected.append((topic, msg_type, t, i))
    rec.add_metadata('params', {'preset': 'tr12x3', 'dt': '0.001'})
    rec.close()
    rec.close()                                  # idempotent
    assert rec.error is None and rec.messages_written == len(expected) == 240
    assert rec.bytes_written == path.stat().st_size

    got, summary, metadata = _read_mcap(path)
    assert [(t, s, lt) for t, s, lt, _ in got] == [e[:3] for e in expected]
    for (topic, _, _, msg), (_, _, _, i) in zip(got, expected):
        _check_values(topic, msg, i)
    assert summary is not None and summary.statistics.message_count == 240
    assert sorted(summary.statistics.channel_message_counts.values()) == [60] * 4
    assert summary.chunk_indexes and all(ci.message_index_offsets for ci in summary.chunk_indexes)
    assert {s.encoding for s in summary.schemas.values()} == {'ros2msg'}
    assert {c.message_encoding for c in summary.channels.values()} == {'cdr'}
    with open(path, 'rb') as f:
        first = next(iter(StreamReader(f).records))
    assert first.profile == 'ros2' and 'leadscrew_sim' in first.library

    assert metadata['params'] == {'preset': 'tr12x3', 'dt': '0.001'}
    bag = yaml.safe_load(metadata['rosbag2']['serialized_metadata'])
    assert bag['version'] == 9 and bag['storage_identifier'] == 'mcap'
    assert bag['message_count'] == 240 and bag['ros_distro'] == 'jazzy'
    assert bag['duration']['nanoseconds'] == expected[-1][2] - expected[0][2]
    assert bag['starting_time']['nanoseconds_since_epoch'] == expected[0][2]
    assert {t['topic_metadata']['name']: t['message_count']
            for t in bag['topics_with_message_count']} == {topic: 60 for topic in ids}
    assert bag['relative_file_paths'] == ['four.mcap'] and bag['files'][0]['message_count'] == 240

    got = _read_rosbags(path)
    assert [(t, s, lt) for t, s, lt, _ in got] == [e[:3] for e in expected]
    for (topic, _, _, msg), (_, _, _, i) in zip(got, expected):
        _check_values(topic, msg, i)
    with AnyReader([path]) as reader:
        for conn in reader.connections:
            (qos,) = conn.ext.offered_qos_profiles
            assert (qos.reliability.name, qos.durability.name, qos.depth) == \
                ('RELIABLE', 'VOLATILE', 10)


def _share_msg(pkg, name):
    path = Path(get_package_share_directory(pkg)) / 'msg' / f'{name}.msg'
    return path.read_bytes().decode()


def test_joint_state_schema_text_is_rosbag2_form(tmp_path):
    expected = (_share_msg('sensor_msgs', 'JointState')
                + '\n' + SEP + '\nMSG: std_msgs/Header\n' + _share_msg('std_msgs', 'Header')
                + '\n' + SEP + '\nMSG: builtin_interfaces/Time\n'
                + _share_msg('builtin_interfaces', 'Time'))
    assert ros2msg_definition('sensor_msgs/msg/JointState') == expected
    rec = McapRecorder(tmp_path / 'js.mcap')
    rec.add_channel('/joint_states', 'sensor_msgs/msg/JointState')
    rec.close()
    with open(tmp_path / 'js.mcap', 'rb') as f:
        (schema,) = make_reader(f).get_summary().schemas.values()
    assert schema.name == 'sensor_msgs/msg/JointState' and schema.encoding == 'ros2msg'
    assert schema.data.decode() == expected


def test_dependencies_sorted_depth_first_once():
    # rosbag2 keeps each file's dependencies in a std::set: sorted, not by appearance.
    text = ros2msg_definition('diagnostic_msgs/msg/DiagnosticArray')
    assert re.findall(r'^MSG: (\S+)$', text, re.M) == [
        'diagnostic_msgs/DiagnosticStatus', 'diagnostic_msgs/KeyValue', 'std_msgs/Header',
        'builtin_interfaces/Time']
    assert 'byte OK=0' in text                       # constants stay in the text
    text = ros2msg_definition('geometry_msgs/msg/WrenchStamped')
    assert re.findall(r'^MSG: (\S+)$', text, re.M) == [
        'geometry_msgs/Wrench', 'geometry_msgs/Vector3', 'std_msgs/Header',
        'builtin_interfaces/Time']


def test_cdr_length_matches_independent_serializer():
    store = get_typestore(Stores.ROS2_JAZZY)
    for i in (0, 1, 2):
        for _, msg_type, msg in _msgs(i):
            data = serialize_message(msg)
            end = cdr_length(msg_type, data)
            assert end <= len(data)
            assert deserialize_message(data[:end], type(msg)) == msg
            decoded = store.deserialize_cdr(data[:end], msg_type)   # strict size check
            assert len(store.serialize_cdr(decoded, msg_type)) == end


CHILD = textwrap.dedent('''
    import signal, sys, time
    from rclpy.serialization import serialize_message
    from std_msgs.msg import Float64
    from leadscrew_sim.io.mcap_file import McapRecorder
    path, mode, flush = sys.argv[1], sys.argv[2], float(sys.argv[3])
    rec = McapRecorder(path, flush_interval=flush)
    cid = rec.add_channel('/x', 'std_msgs/msg/Float64')
    if mode == 'term':
        signal.signal(signal.SIGTERM, lambda *a: rec.close())
    print('ready', flush=True)
    i = 0
    while not rec.closed:
        rec.write(cid, serialize_message(Float64(data=float(i))), time.time_ns())
        print(i, time.monotonic(), flush=True)
        i += 1
        time.sleep(0.005)
    print('closed', rec.error, flush=True)
''')


def _start_child(tmp_path, path, mode):
    script = tmp_path / 'child.py'
    script.write_text(CHILD)
    env = dict(os.environ, PYTHONPATH=str(REPO) + os.pathsep + os.environ.get('PYTHONPATH', ''))
    proc = subprocess.Popen([sys.executable, str(script), str(path), mode, str(FLUSH)],
                            stdout=subprocess.PIPE, text=True, env=env, cwd=REPO)
    assert proc.stdout.readline().strip() == 'ready'
    written = []
    while not written or written[-1][1] - written[0][1] < 2.0:
        i, t = proc.stdout.readline().split()
        written.append((int(i), float(t)))
    return proc, written


def _parse(text):
    """Return the (index, monotonic time) lines the child printed."""
    found = (re.fullmatch(r'(\d+) ([\d.]+)', ln.strip()) for ln in text.splitlines())
    return [(int(m[1]), float(m[2])) for m in found if m]


@pytest.mark.alone     # times a child process against its flush interval
def test_sigkill_loses_at_most_flush_interval(tmp_path):
    path = tmp_path / 'killed.mcap'
    proc, written = _start_child(tmp_path, path, 'kill')
    t_kill = time.monotonic()
    proc.send_signal(signal.SIGKILL)
    rest = proc.stdout.read()
    proc.wait(timeout=10)
    written += _parse(rest)
    assert not _complete(path)                      # the killed file really lacks its summary

    out = tmp_path / 'recovered.mcap'
    n = len(recover(path, out).messages)
    must = [i for i, t in written if t < t_kill - (FLUSH + MARGIN)]
    print(f'must {len(must)} of {len(written)} printed, recovered {n}')
    assert len(must) > 100                           # ~2 s at ~200 Hz minus 0.5 s
    assert len(must) <= n <= len(written) + 1        # +1: killed between write and print
    got, summary, _ = _read_mcap(out)
    assert summary.statistics.message_count == n
    assert [m.data for _, _, _, m in got] == [float(i) for i in range(n)]
    assert [m.data for _, _, _, m in _read_rosbags(out)] == [float(i) for i in range(n)]


def test_sigterm_handler_close_leaves_complete_file(tmp_path):
    path = tmp_path / 'term.mcap'
    proc, written = _start_child(tmp_path, path, 'term')
    proc.send_signal(signal.SIGTERM)
    rest, _ = proc.communicate(timeout=10)
    assert proc.returncode == 0 and 'closed None' in rest
    written += _parse(rest)
    assert _complete(path)
    got, summary, metadata = _read_mcap(path)
    n = summary.statistics.message_count
    assert len(written) - 1 <= n <= len(written) and 'rosbag2' in metadata
    assert [m.data for _, _, _, m in got] == [float(i) for i in range(n)]


def test_io_errors_set_error_and_never_raise(tmp_path):
    data = serialize_message(Float64(data=1.0))
    (tmp_path / 'adir').mkdir()
    (tmp_path / 'afile').write_text('x')
    cases = {'/dev/full': 'no space left', tmp_path / 'adir': 'is a directory',
             tmp_path / 'afile' / 'x.mcap': 'not a directory'}
    if os.geteuid() != 0:                             # root ignores directory permissions
        (tmp_path / 'ro').mkdir(mode=0o500)
        cases[tmp_path / 'ro' / 'x.mcap'] = 'permission denied'
    for target, words in cases.items():
        rec = McapRecorder(target, flush_interval=0.0)
        cid = rec.add_channel('/x', 'std_msgs/msg/Float64')
        for k in range(3):
            rec.write(cid, data, k)
        rec.add_metadata('m', {'a': 'b'})
        rec.flush()
        rec.close()
        assert rec.error and words in rec.error.lower() and '\n' not in rec.error, rec.error
    session = RecordingSession(StorageOptions(tmp_path / 'afile'))
    cid = session.add_channel('/x', 'std_msgs/msg/Float64')
    session.write(cid, data, 1)
    session.close()
    assert 'not a directory' in session.error.lower() or 'file exists' in session.error.lower()


def test_split_by_size_gives_complete_files(tmp_path):
    session = RecordingSession(StorageOptions(tmp_path / 'runs', prefix='lab-1', split_bytes=16384,
                                              flush_interval=10.0),
                               metadata={'params': {'preset': 'p'}})
    ids = {'/never': session.add_channel('/never', 'std_msgs/msg/Float64')}   # no messages
    total = 1500
    for i in range(total // 4 - 1):
        for topic, msg_type, msg in _msgs(i):
            ids.setdefault(topic, session.add_channel(topic, msg_type))
            session.write(ids[topic], serialize_message(msg), 10**9 + 10**6 * i)
    session.close()
    assert session.error is None and session.messages_written == 4 * (total // 4 - 1)
    files = session.files
    assert len(files) >= 3 and files[-1] == session.current_path
    assert all(re.fullmatch(r'lab-1_\d{8}-\d{6}_\d{3}\.mcap', Path(f).name) for f in files)
    assert session.bytes_written == sum(Path(f).stat().st_size for f in files)
    assert all(Path(f).stat().st_size >= 16384 for f in files[:-1])
    count, decoded = 0, []
    for f in files:
        assert _complete(f)
        got, summary, metadata = _read_mcap(f)
        assert {c.id: c.topic for c in summary.channels.values()} == \
            {cid: t for t, cid in ids.items()}
        assert metadata['params'] == {'preset': 'p'}
        assert yaml.safe_load(metadata['rosbag2']['serialized_metadata'])['message_count'] == \
            summary.statistics.message_count == len(got)
        assert [(t, lt) for t, _, lt, _ in _read_rosbags(f)] == [(t, lt) for t, _, lt, _ in got]
        count += len(got)
        decoded += got
    assert count == session.messages_written
    for k, (topic, _, _, msg) in enumerate(decoded):
        _check_values(topic, msg, k // 4)


def test_split_by_log_time(tmp_path):
    session = RecordingSession(StorageOptions(tmp_path, split_seconds=2.0))
    cid = session.add_channel('/x', 'std_msgs/msg/Float64')
    for k in range(1000):                             # 10 s of log time at 100 Hz
        session.write(cid, serialize_message(Float64(data=float(k))), 10**7 * k)
    session.close()
    spans = []
    for f in session.files:
        got, _, _ = _read_mcap(f)
        spans.append((got[0][2], got[-1][2]))
    assert spans == [(2 * 10**9 * j, 2 * 10**9 * j + 199 * 10**7) for j in range(5)]


def test_recover_of_complete_file_keeps_everything(tmp_path):
    rec = McapRecorder(tmp_path / 'ok.mcap')
    cid = rec.add_channel('/x', 'std_msgs/msg/Float64')
    for k in range(50):
        rec.write(cid, serialize_message(Float64(data=float(k))), k)
    rec.add_metadata('params', {'a': '1'})
    rec.close()
    assert len(recover(tmp_path / 'ok.mcap', tmp_path / 'copy.mcap').messages) == 50
    got, summary, metadata = _read_mcap(tmp_path / 'copy.mcap')
    assert [m.data for *_, m in got] == [float(k) for k in range(50)]
    assert metadata['params'] == {'a': '1'} and 'rosbag2' in metadata


@pytest.mark.parametrize('prefix', ['../x', 'a/b', '', 'a' * 65, 'a b', '.hidden'])
def test_prefix_validation(tmp_path, prefix):
    with pytest.raises(ValueError, match='record_prefix'):
        RecordingSession(StorageOptions(tmp_path, prefix=prefix))
    assert list(tmp_path.iterdir()) == []


def test_every_split_file_starts_with_the_latched_topics(tmp_path):
    from leadscrew_sim.io.qos import qos_profile_yaml
    session = RecordingSession(StorageOptions(tmp_path, split_seconds=2.0))
    latched = session.add_channel('/robot_description', 'std_msgs/msg/String',
                                  qos_profile_yaml(durability='transient_local', depth=1))
    cid = session.add_channel('/x', 'std_msgs/msg/Float64')
    session.write(latched, serialize_message(String(data='<robot/>')), 0)
    for k in range(600):                              # 6 s of log time at 100 Hz
        session.write(cid, serialize_message(Float64(data=float(k))), 10**7 * k)
    session.close()
    assert len(session.files) == 3
    for j, f in enumerate(session.files):
        got, _, _ = _read_mcap(f)
        first = got[0]
        assert first[0] == '/robot_description' and first[3].data == '<robot/>', (j, first)
        assert first[2] == 2 * 10**9 * j              # at the file's first log time
        assert [t for t, *_ in got].count('/robot_description') == 1
