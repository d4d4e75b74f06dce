"""
rosbag2 bags as recordings: our reader against rosbags' (an independent reader and writer).

Each bag is written by rosbags in ros2_control's layout; what
:class:`leadscrew_sim.io.rosbag2.BagRecording` reads is compared with what
rosbags' own Reader reads of the same bag: every message, in log-time
order, with its topic and type. Also: split files, zstd and lz4 chunks, a
cut last file (read up to its last whole chunk, as the mcap library's chunk
index places it), rosbag2's file compression refused in one line, sqlite3
storage, the new CDR decoders against rosbags' deserialisation, and the
JointTrajectory sampling against scipy's interpolants.
"""
import os
from pathlib import Path
import shutil
import subprocess
import sys

import bag_factory as B
from helpers import cli
import numpy as np
import pytest
from rosbags.rosbag2 import Reader, StoragePlugin, Writer
from rosbags.rosbag2.enums import CompressionFormat, CompressionMode
import yaml

from leadscrew_sim.io import cdr as C
from leadscrew_sim.io import joint_states as JS
from leadscrew_sim.io.mcap_reader import RecordingError
from leadscrew_sim.io.rosbag2 import BagRecording
from leadscrew_sim.offline.options import open_recording

T = B.TYPESTORE.types


def _messages(n=3000, seed=3):
    """Return [(log time, topic, type, message)]: states every 2-10 ms, commands at 100 Hz."""
    rng = np.random.default_rng(seed)
    out, t = [], B.EPOCH
    for i in range(n):
        t += int(rng.integers(2, 11)) * 1_000_000 + int(rng.integers(0, 50_000))
        pos = rng.normal(size=2)
        out.append((t + 100_000, B.STATES, 'sensor_msgs/msg/JointState',
                    B.joint_state(t, (B.SCREW, B.NUT), pos, pos * 2, [] if i % 7 else pos)))
    for i in range(0, (t - B.EPOCH) // 10_000_000):
        tc = B.EPOCH + i * 10_000_000 + 7
        out.append((tc, B.FORWARD, 'std_msgs/msg/Float64MultiArray',
                    B.multi_array([float(i), 1e-4 * i])))
        if i % 50 == 0:
            out.append((tc, B.TRAJECTORY, 'trajectory_msgs/msg/JointTrajectory',
                        B.trajectory(0 if i % 100 else tc, (B.NUT,),
                                     [([1e-3 * i], [0.01], 500_000_000),
                                      ([1e-3 * i + 1e-3], [0.0], 1_000_000_000)])))
    return out


def _rosbags(path):
    """Return [(log time, topic, type, bytes)] as rosbags' Reader reads the bag, in its order."""
    with Reader(path) as r:
        return [(t, c.topic, c.msgtype, bytes(raw)) for c, t, raw in r.messages()]


def _ours(path):
    rec = open_recording(path)
    return [(t, topic, rec.topic_types[topic], bytes(d)) for t, topic, d in rec.messages], rec


def _same_order(a, b):
    """Compare two message lists as sets of log-time ties (rosbags orders ties its own way)."""
    assert [m[0] for m in a] == [m[0] for m in b]
    assert sorted(a) == sorted(b)


def test_a_bag_reads_as_rosbags_reads_it(tmp_path):
    """Every message, topic and type of a one-file bag, and topic_arrays through the indexes."""
    bag = B.write_bag(tmp_path / 'bag', _messages())
    ours, rec = _ours(bag)
    theirs = _rosbags(bag)
    assert len(theirs) > 3000
    _same_order(ours, theirs)
    assert rec.summary is not None and not rec.cut
    topics = [B.STATES, B.FORWARD, B.TRAJECTORY]
    arrays = rec.topic_arrays(topics)
    for topic in topics:
        want = [(t, d) for t, tp, _ty, d in theirs if tp == topic]
        got = list(zip(arrays[topic].log_times.tolist(),
                       [bytes(m) for m in arrays[topic].messages()]))
        assert got == want
    st = rec.statistics()
    assert st.message_count == len(theirs)
    assert st.message_start_time == theirs[0][0] and st.message_end_time == theirs[-1][0]


def test_a_bag_split_in_two_files_is_merged_in_log_time_order(tmp_path):
    """Two files under one metadata.yaml: one recording, as rosbags reads the split bag."""
    msgs = _messages()
    mid = sorted(m[0] for m in msgs)[len(msgs) // 2]
    bag = B.split_bag(tmp_path / 'split', msgs, mid)
    assert len(list(bag.glob('*.mcap'))) == 2
    ours, rec = _ours(bag)
    _same_order(ours, _rosbags(bag))
    assert len(rec.files) == 2 and len(rec.channels) == 3
    arrays = rec.topic_arrays([B.STATES])[B.STATES]
    assert (np.diff(arrays.log_times) >= 0).all()
    assert len(arrays.log_times) == sum(1 for m in msgs if m[1] == B.STATES)


def _rewrite_lz4(src, dst):
    """Rewrite an MCAP file by the mcap library's writer in lz4 chunks (schemas, channels kept)."""
    from mcap.reader import make_reader
    from mcap.writer import CompressionType, Writer as McapWriter
    with open(src, 'rb') as fi, open(dst, 'wb') as fo:
        reader = make_reader(fi)
        w = McapWriter(fo, compression=CompressionType.LZ4, chunk_size=64 * 1024)
        w.start(profile='ros2', library='test lz4')
        schemas, channels = {}, {}
        for schema, channel, msg in reader.iter_messages(log_time_order=False):
            if schema.id not in schemas:
                schemas[schema.id] = w.register_schema(schema.name, schema.encoding, schema.data)
            if channel.id not in channels:
                channels[channel.id] = w.register_channel(channel.topic,
                                                          channel.message_encoding,
                                                          schemas[schema.id], channel.metadata)
            w.add_message(channels[channel.id], msg.log_time, msg.data, msg.publish_time,
                          msg.sequence)
        w.finish()


@pytest.mark.parametrize('compression', ['zstd', 'lz4'])
def test_zstd_and_lz4_chunks(tmp_path, compression):
    """The zstd chunks of rosbags' storage compression and lz4 chunks of the mcap library."""
    msgs = _messages(1500)
    bag = B.write_bag(tmp_path / 'bag', msgs, compress=compression == 'zstd')
    if compression == 'lz4':
        f = next(bag.glob('*.mcap'))
        _rewrite_lz4(f, tmp_path / 'lz4.mcap')
        shutil.move(tmp_path / 'lz4.mcap', f)
    from mcap.reader import make_reader
    with open(next(bag.glob('*.mcap')), 'rb') as fh:
        kinds = {c.compression for c in make_reader(fh).get_summary().chunk_indexes}
    assert kinds == {compression}
    ours, _rec = _ours(bag)
    _same_order(ours, _rosbags(bag))


def test_a_cut_last_file_is_read_up_to_its_last_whole_chunk(tmp_path):
    """A crash cut the second file in its third chunk: what the whole chunks hold; a warning."""
    msgs = _messages(20000)
    mid = sorted(m[0] for m in msgs)[len(msgs) // 3]
    whole = B.split_bag(tmp_path / 'whole', msgs, mid)
    theirs = _rosbags(whole)
    cut = tmp_path / 'cut'
    shutil.copytree(whole, cut)
    last = cut / 'cut_1.mcap' if (cut / 'cut_1.mcap').exists() else sorted(cut.glob('*.mcap'))[-1]
    from mcap.reader import make_reader
    with open(last, 'rb') as fh:
        chunks = sorted(make_reader(fh).get_summary().chunk_indexes,
                        key=lambda c: c.chunk_start_offset)
    assert len(chunks) >= 3
    stop = chunks[2].chunk_start_offset + chunks[2].chunk_length // 2
    with open(last, 'r+b') as fh:
        fh.truncate(stop)
    # the oracle: rosbags' messages of the first file and of the two whole chunks of the second
    end_time = chunks[1].message_end_time
    first_file = [m for m in theirs if m[0] < mid]
    kept = first_file + [m for m in theirs if mid <= m[0] <= end_time]
    r = subprocess.run([sys.executable, '-c', 'import sys; from leadscrew_sim.offline.options '
                        'import open_recording as o; r = o(sys.argv[1]); print(len(r.messages))',
                        str(cut)], capture_output=True, text=True, env=dict(os.environ))
    assert r.returncode == 0, r.stderr
    assert int(r.stdout) == len(kept)
    warning = [ln for ln in r.stderr.splitlines() if ln.strip()]
    assert len(warning) == 1 and 'cut short' in warning[0] and 'recover' in warning[0], r.stderr
    ours, rec = _ours(cut)
    _same_order(ours, kept)
    assert rec.cut and rec.summary is None
    arrays = rec.topic_arrays([B.STATES])[B.STATES]
    assert len(arrays.log_times) == sum(1 for m in kept if m[1] == B.STATES)
    # recover writes the bag as one complete file that mcap doctor and rosbags accept
    out = tmp_path / 'recovered.mcap'
    res = cli('recover', cut, '-o', out)
    assert res.returncode == 0, res.stderr
    ran, ok, text = B.mcap_doctor(out)
    assert ok, text
    from mcap_ros2.reader import read_ros2_messages
    got = sorted((m.log_time_ns, m.channel.topic) for m in read_ros2_messages(str(out)))
    assert got == sorted((m[0], m[1]) for m in kept)


@pytest.mark.parametrize('mode', [CompressionMode.FILE, CompressionMode.MESSAGE])
def test_rosbag2_compression_is_refused_in_one_line(tmp_path, mode):
    """compression_mode FILE or MESSAGE: one line that says so, for every verb."""
    w = Writer(tmp_path / 'bag', version=9, storage_plugin=StoragePlugin.MCAP)
    w.set_compression(mode, CompressionFormat.ZSTD)
    with w:
        c = w.add_connection(B.STATES, 'sensor_msgs/msg/JointState', typestore=B.TYPESTORE)
        for i in range(10):
            w.write(c, B.EPOCH + i, B.TYPESTORE.serialize_cdr(
                B.joint_state(B.EPOCH + i, (B.SCREW,), [0.0], [], []),
                'sensor_msgs/msg/JointState'))
    info = yaml.safe_load((tmp_path / 'bag' / 'metadata.yaml').read_text())
    assert info['rosbag2_bagfile_information']['compression_mode'] == mode.name.lower()
    with pytest.raises(RecordingError, match=f'compression_mode {mode.name}'):
        BagRecording(tmp_path / 'bag')
    for verb in ('info', 'resim', 'identify', 'plot', 'recover'):
        r = cli(verb, tmp_path / 'bag')
        lines = [ln for ln in r.stderr.splitlines() if ln.strip()]
        assert r.returncode == 1 and len(lines) == 1, (verb, r.stderr)
        assert lines[0].startswith('leadscrew_sim: error:') and 'compression' in lines[0]


def test_a_sqlite3_bag_reads_as_rosbags_reads_it(tmp_path):
    """The .db3 storage: the same messages, topics and types as rosbags reads."""
    msgs = _messages(800)
    with Writer(tmp_path / 'db', version=9, storage_plugin=StoragePlugin.SQLITE3) as w:
        conns = {}
        for t, topic, mtype, msg in sorted(msgs, key=lambda m: m[0]):
            if topic not in conns:
                conns[topic] = w.add_connection(topic, mtype, typestore=B.TYPESTORE)
            w.write(conns[topic], t, B.TYPESTORE.serialize_cdr(msg, mtype))
    assert list((tmp_path / 'db').glob('*.db3'))
    ours, rec = _ours(tmp_path / 'db')
    assert rec.storage == 'sqlite3'
    _same_order(ours, _rosbags(tmp_path / 'db'))


def test_a_directory_that_is_no_bag_gives_one_line(tmp_path):
    """An empty directory, and a listed split file that is missing: one line each."""
    r = cli('info', tmp_path)
    assert r.returncode == 1 and 'not a rosbag2 bag' in r.stderr, r.stderr
    bag = B.write_bag(tmp_path / 'bag', _messages(50))
    next(bag.glob('*.mcap')).unlink()
    r = cli('info', bag)
    lines = r.stderr.strip().splitlines()
    assert r.returncode == 1 and len(lines) == 1 and 'is not there' in lines[0], r.stderr


def test_cdr_decoders_against_rosbags():
    """Float64MultiArray, JointTrajectory and JointState columns as rosbags deserialises them."""
    rng = np.random.default_rng(5)
    ma = T['std_msgs/msg/Float64MultiArray'](
        layout=T['std_msgs/msg/MultiArrayLayout'](dim=[T['std_msgs/msg/MultiArrayDimension'](
            label='joints', size=3, stride=3)], data_offset=1), data=rng.normal(size=3))
    raw = B.TYPESTORE.serialize_cdr(ma, 'std_msgs/msg/Float64MultiArray')
    assert C.decode_float64_multi_array(bytes(raw)) == tuple(ma.data)
    tr = B.trajectory(B.EPOCH, ('a', 'bb', 'ccc'), [(rng.normal(size=3), [], 10),
                                                    (rng.normal(size=3), rng.normal(size=3),
                                                     2_000_000_001)])
    raw = bytes(B.TYPESTORE.serialize_cdr(tr, 'trajectory_msgs/msg/JointTrajectory'))
    back = B.TYPESTORE.deserialize_cdr(raw, 'trajectory_msgs/msg/JointTrajectory')
    stamp, names, points = C.decode_joint_trajectory(raw)
    assert stamp == back.header.stamp.sec * B.NS + back.header.stamp.nanosec
    assert names == list(back.joint_names)
    for (pos, vel, _acc, _eff, tfs), p in zip(points, back.points):
        assert pos == tuple(p.positions) and vel == tuple(p.velocities)
        assert tfs == p.time_from_start.sec * B.NS + p.time_from_start.nanosec
    # JointStates of varying layouts (empty arrays, another joint order): NaN where none
    msgs = [B.joint_state(B.EPOCH + 5, ('x', 'y'), [1.0, 2.0], [], [3.0, 4.0]),
            B.joint_state(B.EPOCH + 9, ('y', 'x'), [5.0, 6.0], [7.0, 8.0], [])]
    raws = [bytes(B.TYPESTORE.serialize_cdr(m, 'sensor_msgs/msg/JointState')) for m in msgs]
    stamps, names, pos, vel, eff = JS.joint_state_columns(raws)
    assert stamps.tolist() == [B.EPOCH + 5, B.EPOCH + 9] and names == ['x', 'y']
    assert pos.tolist() == [[1.0, 2.0], [6.0, 5.0]]
    assert np.isnan(vel[0]).all() and vel[1].tolist() == [8.0, 7.0]
    assert eff[0].tolist() == [3.0, 4.0] and np.isnan(eff[1]).all()


def test_trajectory_sampling_against_scipy():
    """Linear between positions, cubic Hermite with velocities: as numpy and scipy interpolate."""
    from scipy.interpolate import CubicHermiteSpline
    from leadscrew_sim.offline.foreign.commands import _piecewise
    at = np.array([0, 300, 1000, 1600], dtype=np.int64) * 1_000_000
    pos = np.array([0.0, 0.004, 0.001, 0.003])
    vel = np.array([0.0, 0.01, -0.02, 0.0])
    t = np.arange(-50, 1700, 1, dtype=np.int64) * 1_000_000
    got, _v = _piecewise(t, at, pos, None)
    assert np.allclose(got, np.interp(t, at, pos), rtol=0, atol=1e-15)
    got, _v = _piecewise(t, at, pos, vel)
    spline = CubicHermiteSpline(at / 1e9, pos, vel)
    inside = (t >= at[0]) & (t <= at[-1])
    assert np.allclose(got[inside], spline(t[inside] / 1e9), rtol=0, atol=1e-15)
    assert (got[t < at[0]] == pos[0]).all() and (got[t > at[-1]] == pos[-1]).all()


def test_a_bag_directory_path_object_and_string_alike(tmp_path):
    """open_recording takes the bag as str or Path; the recording's path is the directory."""
    bag = B.write_bag(tmp_path / 'bag', _messages(100))
    a, b = open_recording(str(bag)), open_recording(Path(bag))
    assert a.path == b.path == str(bag) and len(a.messages) == len(b.messages) > 0
