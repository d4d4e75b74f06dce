"""
Our MCAP writer against the MCAP spec and the independent ``mcap`` reader.

The oracle is the spec (https://mcap.dev/spec) for the byte layout of the
index records, and the ``mcap`` library's readers (with CRC validation) for
everything they decode. Bulk rows (``add_rows``) and single messages
(``add_message``) must give the same messages.
"""
import io
import struct
import zlib

from mcap.reader import make_reader
from mcap.records import Footer, Header, Message
from mcap.stream_reader import StreamReader
import numpy as np
import pytest
import zstandard

from leadscrew_sim.io.mcap_writer import MAGIC, McapWriter


def messages(n, sizes=(8, 13, 40)):
    """Return n rows of deterministic pseudo-random payloads, one array per channel."""
    rng = np.random.default_rng(7)
    return [rng.integers(0, 256, size=(n, s), dtype=np.uint8) for s in sizes]


def write(n, bulk, chunk_size, sizes=(8, 13, 40)):
    """Write n rows of 3 channels; times: row k at 1000 k ns (+ j for channel j)."""
    out = io.BytesIO()
    w = McapWriter(out, profile='ros2', library='test', chunk_size=chunk_size)
    sid = w.register_schema('pkg/msg/T', 'ros2msg', b'float64 data')
    cids = [w.register_channel(f'/t{j}', 'cdr', sid, {'k': str(j)}) for j in range(len(sizes))]
    w.add_metadata('first', {'a': '1'})
    pay = messages(n, sizes)
    times = [np.arange(n, dtype=np.int64) * 1000 + j for j in range(len(sizes))]
    if bulk:
        # in three uneven blocks, as simulate writes them
        for a, b in ((0, n // 3), (n // 3, n // 3 + 1), (n // 3 + 1, n)):
            w.add_rows(cids, [p[a:b] for p in pay], [t[a:b] for t in times],
                       [np.arange(a, b)] * len(sizes))
    else:
        for k in range(n):
            for j, cid in enumerate(cids):
                w.add_message(cid, int(times[j][k]), pay[j][k].tobytes(), int(times[j][k]), k)
    w.add_metadata('last', {'b': '2'})
    w.finish()
    return out.getvalue(), pay, times


@pytest.mark.parametrize('bulk', [False, True], ids=['add_message', 'add_rows'])
@pytest.mark.parametrize('chunk_size', [1 << 20, 777], ids=['one_chunk', 'many_chunks'])
def test_mcap_reader_decodes_every_message_with_crcs_checked(bulk, chunk_size):
    n = 500
    data, pay, times = write(n, bulk, chunk_size)
    assert data.startswith(MAGIC) and data.endswith(MAGIC)
    # streaming pass: every chunk CRC and record framing checked by mcap
    records = list(StreamReader(io.BytesIO(data), validate_crcs=True).records)
    assert isinstance(records[0], Header) and records[0].profile == 'ros2'
    assert isinstance(records[-1], Footer)
    got = [r for r in records if isinstance(r, Message)]
    assert len(got) == 3 * n
    # indexed pass: summary, chunk indexes, log-time order
    reader = make_reader(io.BytesIO(data), validate_crcs=True)
    summary = reader.get_summary()
    st = summary.statistics
    assert (st.message_count, st.channel_count, st.schema_count, st.metadata_count) == (
        3 * n, 3, 1, 2)
    assert st.message_start_time == 0 and st.message_end_time == 1000 * (n - 1) + 2
    assert dict(st.channel_message_counts) == {1: n, 2: n, 3: n}
    assert st.chunk_count == len(summary.chunk_indexes)
    if chunk_size < 1000:
        assert st.chunk_count > 10
    seen = {1: [], 2: [], 3: []}
    last = -1
    for _schema, channel, msg in reader.iter_messages(log_time_order=True):
        assert msg.log_time >= last
        last = msg.log_time
        seen[channel.id].append(msg)
    for j in range(3):
        ms = seen[j + 1]
        assert [m.log_time for m in ms] == times[j].tolist()
        assert [m.publish_time for m in ms] == times[j].tolist()
        assert [m.sequence for m in ms] == list(range(n))
        assert all(m.data == pay[j][k].tobytes() for k, m in enumerate(ms))
    assert {m.name: m.metadata for m in reader.iter_metadata()} == {
        'first': {'a': '1'}, 'last': {'b': '2'}}


def _u64(data, at):
    return struct.unpack_from('<Q', data, at)[0]


@pytest.mark.parametrize('bulk', [False, True], ids=['add_message', 'add_rows'])
def test_index_records_point_where_the_spec_says(bulk):
    """Chunk indexes, message indexes, summary offsets and the footer CRC, by the spec."""
    n = 300
    data, _pay, _times = write(n, bulk, 1500)
    summary = make_reader(io.BytesIO(data)).get_summary()
    count = 0
    for ci in summary.chunk_indexes:
        at = ci.chunk_start_offset
        assert data[at] == 0x06 and _u64(data, at + 1) + 9 == ci.chunk_length
        # Chunk: start, end, uncompressed size, uncompressed crc, compression, records
        t0, t1, usize, ucrc, clen = struct.unpack_from('<QQQII', data, at + 9)
        comp = data[at + 41:at + 41 + clen].decode()
        (rlen,) = struct.unpack_from('<Q', data, at + 41 + clen)
        packed = data[at + 49 + clen:at + 49 + clen + rlen]
        assert at + 49 + clen + rlen == at + ci.chunk_length
        assert (t0, t1, comp) == (ci.message_start_time, ci.message_end_time, 'zstd')
        raw = zstandard.ZstdDecompressor().decompress(packed, max_output_size=usize)
        assert len(raw) == usize == ci.uncompressed_size and zlib.crc32(raw) == ucrc
        assert rlen == ci.compressed_size
        # message index records follow the chunk, one per channel, at the given offsets
        assert min(ci.message_index_offsets.values()) == at + ci.chunk_length
        for cid, mi_at in ci.message_index_offsets.items():
            assert data[mi_at] == 0x07
            ch, nbytes = struct.unpack_from('<HI', data, mi_at + 9)
            assert ch == cid
            for e in range(nbytes // 16):
                log_time, off = struct.unpack_from('<QQ', data, mi_at + 15 + 16 * e)
                assert raw[off] == 0x05
                m_ch, _seq, m_log = struct.unpack_from('<HIQ', raw, off + 9)
                assert (m_ch, m_log) == (cid, log_time)
                assert ci.message_start_time <= log_time <= ci.message_end_time
                count += 1
    assert count == 3 * n
    # footer: summary start, summary offsets, CRC over summary .. footer fields
    foot = len(data) - 8 - 29
    assert data[foot] == 0x02
    s_start, so_start, crc = struct.unpack_from('<QQI', data, foot + 9)
    assert zlib.crc32(data[s_start:foot + 9 + 16]) == crc
    groups = {}
    at = so_start
    while at < foot:
        assert data[at] == 0x0E
        op, g_start, g_len = struct.unpack_from('<BQQ', data, at + 9)
        groups[op] = (g_start, g_len)
        at += 9 + 17
    assert set(groups) == {0x03, 0x04, 0x0B, 0x08, 0x0D}
    for op, (g_start, g_len) in groups.items():
        assert data[g_start] == op
    # Statistics: message_count is its first field
    assert _u64(data, groups[0x0B][0] + 9) == 3 * n


def test_bulk_and_single_give_the_same_file():
    """With one chunk both paths write the same bytes (rows are whole messages in order)."""
    a, _, _ = write(200, False, 1 << 20)
    b, _, _ = write(200, True, 1 << 20)
    assert a == b


def test_unknown_channel_and_ragged_rows_are_refused():
    w = McapWriter(io.BytesIO())
    sid = w.register_schema('pkg/msg/T', 'ros2msg', b'')
    cid = w.register_channel('/t', 'cdr', sid)
    with pytest.raises(ValueError, match='unknown channel id 5'):
        w.add_message(5, 0, b'x', 0)
    with pytest.raises(ValueError, match='unknown channel id 9'):
        w.add_rows([9], [np.zeros((2, 3), np.uint8)], [np.zeros(2)], [np.zeros(2)])
    with pytest.raises(ValueError, match='one row per message'):
        w.add_rows([cid], [np.zeros(3, np.uint8)], [np.zeros(3)], [np.zeros(3)])
    assert w.message_count == 0
