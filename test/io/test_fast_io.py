"""
The offline tools' fast paths give what the slow, independent ones give.

- the chunk walker and the message-index reader of ``Recording`` return the
  messages the ``mcap`` library reads (its own record parser), for zstd,
  lz4 and uncompressed chunks;
- the files of every compression pass ``mcap doctor`` and read back in
  ``rosbags`` with every message;
- messages encoded as they are written (``EncodedRows``) are the bytes of
  the templates' own ``rows`` (themselves checked against rclpy's
  serializer in test_cli), for stamps of both signs and every kind of double;
- the vectorised command sources and ``CommandHold.take_series`` hand the
  drive the doubles the one-by-one path does.
"""
import math
import struct
import subprocess

from mcap.reader import make_reader
import numpy as np
import pytest

import helpers
from helpers import SHARED
from leadscrew_sim.cli import main as cli_main
from leadscrew_sim.offline.simulate.sources import Held, make_torque_source
from leadscrew_sim.core.commands import CommandHold, NutMap
from leadscrew_sim.io import cdr as C
from leadscrew_sim.io import joint_states as JS
from leadscrew_sim.io.mcap_reader import Recording
from leadscrew_sim.io import record_fill as RF
from leadscrew_sim.io.record_fill import EncodedRows, Stamps
from leadscrew_sim.io.tf import TfEncoder, tf_encoded

MCAP_CLI = SHARED / 'mcap-cli' / 'mcap'


def _simulate(tmp_path, compression, *extra):
    out = tmp_path / f'run_{compression}.mcap'
    rc = cli_main(['simulate', '--duration', '0.4', '--excite', 'reversals', '--compression',
                   compression, '-q', '-o', str(out), *extra])
    assert rc == 0
    return out


def _library_messages(path):
    """Return (log_time, topic, data) of every message in file order, read by mcap."""
    with open(path, 'rb') as fh:
        return [(m.log_time, c.topic, bytes(m.data))
                for _s, c, m in make_reader(fh).iter_messages(log_time_order=False)]


@pytest.mark.parametrize('compression', ['zstd', 'lz4', 'none'])
def test_chunk_walker_reads_what_the_mcap_library_reads(tmp_path, compression):
    """Recording.messages equals the mcap library's messages, stably sorted by log time."""
    path = _simulate(tmp_path, compression, '--force', '3')
    expected = sorted(_library_messages(path), key=lambda m: m[0])
    got = [(t, topic, bytes(d)) for t, topic, d in Recording(path).messages]
    assert got == expected
    assert len(got) > 2000          # 400 ticks of 7 topics and more: a real file


@pytest.mark.parametrize('compression', ['zstd', 'lz4'])
def test_topic_arrays_match_the_mcap_library(tmp_path, compression):
    """topic_arrays gives each topic's times and payloads, and ranks by log time, as mcap does."""
    path = _simulate(tmp_path, compression)
    ordered = _library_messages(path)
    rank, seen = [], {}
    for t, _topic, _d in ordered:            # 1 + earlier messages of that log time, any topic
        seen[t] = seen.get(t, 0) + 1
        rank.append(seen[t])
    rec = Recording(path, load_messages=False)
    topics = sorted({topic for _t, topic, _d in ordered})
    arrays = rec.topic_arrays(topics + ['/not_recorded'])
    for topic in topics:
        want = [(t, d, r) for (t, tp, d), r in zip(ordered, rank) if tp == topic]
        a = arrays[topic]
        assert a.log_times.tolist() == [w[0] for w in want]
        assert [bytes(m) for m in a.messages()] == [w[1] for w in want]
        assert a.ranks.tolist() == [w[2] for w in want]
    assert len(arrays['/not_recorded'].log_times) == 0


@pytest.mark.parametrize('compression', ['zstd', 'lz4', 'none'])
def test_every_compression_reads_in_rosbags_and_passes_mcap_doctor(tmp_path, compression):
    """Every message of the file reads back in rosbags; the Go mcap doctor finds no error."""
    from rosbags.highlevel import AnyReader
    path = _simulate(tmp_path, compression)
    n = len(_library_messages(path))
    with AnyReader([path]) as reader:
        assert sum(1 for _ in reader.messages()) == n
    if not MCAP_CLI.exists():
        pytest.skip('no mcap CLI in ../shared/mcap-cli')
    doc = subprocess.run([str(MCAP_CLI), 'doctor', str(path)], capture_output=True, text=True,
                         timeout=60)
    assert doc.returncode == 0 and 'error' not in (doc.stdout + doc.stderr).lower(), \
        doc.stdout + doc.stderr


def _doubles(rng, n):
    """Return n doubles of every kind: normal, tiny, huge, zeros of both signs, inf and NaN."""
    special = np.array([0.0, -0.0, np.inf, -np.inf, np.nan, 5e-324, -1.7976931348623157e308])
    v = rng.standard_normal(n) * 10.0 ** rng.integers(-300, 300, n)
    v[:len(special)] = special
    return v


def test_encoded_rows_are_the_template_rows():
    """Encoded rows are the bytes of Template.rows and TfEncoder.rows, for any slice."""
    rng = np.random.default_rng(7)
    n = 257
    stamps = rng.integers(-2**31 * helpers.NS, 2**31 * helpers.NS - 1, n)
    for template in (C.joint_state_template(['a', 'bb', 'ccc'], 3, 3, 3), C.wrench_template(),
                     C.float64_template()):
        cols = [_doubles(rng, n) for _ in template.offsets]
        want = template.rows(stamps, cols)
        got = EncodedRows.of_template(template, stamps, cols)
        assert np.array_equal(got.tobytes_rows(), want)
        assert np.array_equal(got[10:20].tobytes_rows(), want[10:20])
    enc = TfEncoder([('world', 'screw_link'), ('world', 'nut_link'), ('nut_link', 'x')])
    cols = [_doubles(rng, n) for _ in range(enc.n_values)]
    assert np.array_equal(tf_encoded(enc, stamps, cols).tobytes_rows(), enc.rows(stamps, cols))


def test_compiled_scatter_writes_what_numpy_slicing_writes():
    """The compiled scatter equals plain numpy slice copies, fields at any offset and row."""
    rng = np.random.default_rng(11)
    n, width, k, r = 300, 203, 17, 250
    row = rng.integers(0, 256, width).astype(np.uint8)
    src8 = rng.integers(0, 2**64, (5, n), dtype=np.uint64)
    src4 = rng.integers(0, 2**32, (3, n), dtype=np.uint64).astype(np.uint32)
    dst8 = np.array([0, 8, 51, 100, width - 8], dtype=np.uint64)     # both ends of a row
    dst4 = np.array([4, 97, width - 12], dtype=np.uint64)
    at8, at4 = np.array([4, 0, 2, 2, 1], dtype=np.uint64), np.array([2, 0, 1], dtype=np.uint64)
    want = np.tile(row, (r, 1))
    for u, o in zip(at8.tolist(), dst8.tolist()):
        want[:, o:o + 8] = src8[u, k:k + r].astype('<u8').view(np.uint8).reshape(r, 8)
    for u, o in zip(at4.tolist(), dst4.tolist()):
        want[:, o:o + 4] = src4[u, k:k + r].astype('<u4').view(np.uint8).reshape(r, 4)
    for fn in (RF.scatter, RF._scatter_numpy):
        got = np.empty(r * width, dtype=np.uint8)
        fn(got, width, r, row, k, src8, at8, dst8, src4, at4, dst4)
        assert np.array_equal(got.reshape(r, width), want)


def test_shared_stamps_encode_as_the_int_stamps():
    """A block's Stamps object gives every message the bytes its int stamps give."""
    stamps = np.array([0, 1, 999_999_999, 1_000_000_000, -1, -1_500_000_000, 2**31 * 10**9 - 1])
    template = C.joint_state_template(['a'], 1, 1, 1)
    cols = [np.arange(len(stamps), dtype=float) for _ in template.offsets]
    assert np.array_equal(EncodedRows.of_template(template, Stamps(stamps), cols).tobytes_rows(),
                          template.rows(stamps, cols))


def test_vectorised_sources_hand_the_same_doubles():
    """The block form of every open-loop torque source and of Held equals the scalar calls."""
    class Args:
        torque = torque_csv = None
        amplitude, frequency, step_time, duration = 0.3, 1.7, 0.25, 2.0
        excite = None
    ks = np.arange(0, 3001)
    ts = ks * 1e-3
    for profile in ('sine', 'step', 'ramp'):
        a = Args()
        a.profile = profile
        fn, _desc = make_torque_source(a, None)
        scalar = np.array([fn(int(k), k * 1e-3, None, None) for k in ks])
        assert np.array_equal(fn.block(ts).view(np.int64), scalar.view(np.int64)), profile
    held = Held([0.0, 0.5, 1.0000000000001, 2.0], [1.0, -2.0, 3.0, 4.0], before=-7.0)
    probe = np.concatenate([ts, [-1.0, 0.5 - 1e-12, 0.5 - 2e-12, 1.0, 9.0]])
    assert held.block(probe).tolist() == [held(float(t)) for t in probe]


@pytest.mark.parametrize('kind', ['torque_command', 'velocity_command', 'position_command'])
def test_take_series_equals_one_command_at_a_time(kind):
    """CommandHold.take_series gives the rows of calling the command method and command_at."""
    rng = np.random.default_rng(3)
    values = rng.standard_normal(500) * 1e-2
    times = np.arange(500, dtype=np.int64) * 1_000_000
    nut_map = NutMap(0.3, 0.001, -2.0 * math.pi / 0.003)
    a, b = CommandHold('', 0.1, nut_map), CommandHold('', 0.1, nut_map)
    rows = a.take_series(kind, values, times)
    one = []
    for v, t in zip(values, times):
        assert getattr(b, kind)(float(v), int(t)) is None
        one.append(b.command_at(int(t)))
    assert np.array_equal(np.asarray(one), rows, equal_nan=True)
    assert (a.received, a.command_at(10**9)) == (b.received, b.command_at(10**9))
    assert a.take_series(kind, [1.0, math.nan], times[:2]) is None      # one by one then


def test_bulk_float64_decoding_reads_what_rclpy_wrote():
    """decode_float64s returns the doubles rclpy serialized, bit for bit, as arrays or lists."""
    from rclpy.serialization import serialize_message
    from std_msgs.msg import Float64
    values = _doubles(np.random.default_rng(11), 300)
    messages = [serialize_message(Float64(data=float(v))) for v in values]
    as_rows = np.frombuffer(b''.join(messages), dtype=np.uint8).reshape(-1, 12)
    for given in (messages, as_rows):
        got = C.decode_float64s(given)
        assert np.array_equal(got.view(np.int64), values.view(np.int64))
    big = [b'\x00\x00\x00\x00' + struct.pack('>d', v) for v in values[:5]]  # big-endian CDR
    assert np.array_equal(C.decode_float64s(big).view(np.int64), values[:5].view(np.int64))


def test_joint_state_groups_read_what_rclpy_wrote():
    """
    Mixed JointStates decode by groups into each message's own names and arrays.

    rclpy serializes nut and screw commands, messages with short or empty
    arrays, and one with a frame_id (no template reads it); every message is
    in exactly one group, with the doubles rclpy wrote, bit for bit.
    """
    from rclpy.serialization import serialize_message
    from sensor_msgs.msg import JointState
    rng = np.random.default_rng(5)
    pool = iter(_doubles(rng, 4000))

    def doubles(n):
        return [next(pool) for _ in range(n)]
    written = []
    for i in range(400):
        names = [['nut_joint'], ['screw_joint'], ['screw_joint', 'nut_joint']][i % 3]
        m = len(names)
        pos = doubles(m) if i % 5 else []
        vel = doubles(m if i % 7 else 1)
        eff = doubles(m)
        msg = JointState(name=names, position=pos, velocity=vel, effort=eff)
        msg.header.stamp.sec, msg.header.stamp.nanosec = i, 17 * i
        if i == 123:
            msg.header.frame_id = 'base'
        written.append((names, pos, vel, eff, serialize_message(msg)))
    groups = JS.joint_state_groups([w[-1] for w in written])
    seen = np.concatenate([g[0] for g in groups])
    assert sorted(seen.tolist()) == list(range(len(written)))
    assert any(len(g[0]) == 1 and g[0][0] == 123 for g in groups)
    for index, names, *arrays in groups:
        for row, i in enumerate(index):
            assert names == written[i][0]
            for got, want in zip(arrays, written[i][1:4]):
                assert np.array_equal(got[row].view(np.int64),
                                      np.asarray(want, dtype=float).view(np.int64))
