"""
A small, fast writer of chunked, indexed MCAP files (format version 0).

Why not ``mcap.writer.Writer``: it builds a record object per message and
costs about 12 us per message here; the node's recorder and ``simulate``
write four messages per tick. This writer appends a message with one
``struct`` call (about 1.5 us) and writes whole blocks of fixed-layout
messages with one compiled scatter per block (:meth:`McapWriter.add_rows`,
well under 0.1 us per message). Files are read back in the tests by the independent readers
``mcap`` and ``rosbags``.

Layout written (https://mcap.dev/spec): magic, Header; messages in
zstd- or lz4-compressed (or plain) Chunks, each followed by its Message Index records; Schema
and Channel records go into the open chunk when they are registered, as
rosbag2 writes them (so a file cut short by a crash has every channel before
its messages, and ``mcap recover`` rebuilds a valid file; records registered
with no message after them are written outside a chunk); Metadata records;
Data End; a summary section (Schemas, Channels, Statistics, Chunk Indexes,
Metadata Indexes), Summary Offsets, Footer (with the summary CRC) and the
closing magic. Chunk records carry the CRC-32 of their uncompressed data.
Times are uint64 nanoseconds, sizes bytes.

A chunk is closed only between two log times: once it holds ``chunk_size``
bytes (or a flush is asked for with :meth:`McapWriter.flush_soon`), it
closes before the first message that is later than all it holds. Messages of
one tick share their log time, so a tick never spans two chunks and the
chunks' time ranges do not overlap when the messages come in time order.
"""
import collections
from concurrent.futures import ThreadPoolExecutor
import struct
import zlib

import lz4.frame
import numpy as np
import zstandard

from .record_fill import EncodedRows, RowLayout

MAGIC = b'\x89MCAP0\r\n'

#: The chunk compressions written (MCAP's names): zstd (small files), lz4 (a third larger,
#: compressed about twice and read back about three times as fast), none.
COMPRESSIONS = ('zstd', 'lz4', '')

OP_HEADER, OP_FOOTER, OP_SCHEMA, OP_CHANNEL, OP_MESSAGE = 0x01, 0x02, 0x03, 0x04, 0x05
OP_CHUNK, OP_MESSAGE_INDEX, OP_CHUNK_INDEX = 0x06, 0x07, 0x08
OP_STATISTICS, OP_METADATA, OP_METADATA_INDEX = 0x0B, 0x0C, 0x0D
OP_SUMMARY_OFFSET, OP_DATA_END = 0x0E, 0x0F

#: Message record: opcode, record length, channel id, sequence, log time, publish time.
_MESSAGE = struct.Struct('<BQHIQQ')
MESSAGE_OVERHEAD = _MESSAGE.size          # 31 bytes before the payload
_PREFIX = struct.Struct('<BQ')
_U32 = struct.Struct('<I')
_PAIR = struct.Struct('<HQ')


def _string(s):
    raw = s.encode('utf-8')
    return _U32.pack(len(raw)) + raw


def _string_map(d):
    body = b''.join(_string(k) + _string(v) for k, v in d.items())
    return _U32.pack(len(body)) + body


def _id_map(d):
    body = b''.join(_PAIR.pack(k, v) for k, v in sorted(d.items()))
    return _U32.pack(len(body)) + body


def _record(opcode, body):
    return _PREFIX.pack(opcode, len(body)) + body


class McapWriter:
    """
    Write one MCAP file to a binary stream.

    ``chunk_size``: uncompressed bytes after which a chunk is closed;
    ``compression``: of the chunks, one of :data:`COMPRESSIONS` (``''``: none);
    ``zstd_level``: the zstd level (zstandard's levels; 3 is its default);
    ``background``: a thread of its own compresses the chunks and writes
    everything to the stream, in order, while the caller goes on (the
    compressors and the file write release the GIL); at most three writes
    wait, and an I/O error is raised by the call after it, or by
    :meth:`flush` and :meth:`finish`. The stream is only written to, never sought, so a pipe or
    a file opened ``'wb'`` both work. I/O errors propagate (``OSError``).
    """

    def __init__(self, stream, *, profile='', library='', chunk_size=1 << 20, zstd_level=1,
                 compression='zstd', background=False):
        if compression not in COMPRESSIONS:
            raise ValueError(f'compression {compression!r} is not one of {COMPRESSIONS}')
        self._out = stream
        self._pos = 0
        self._chunk_size = int(chunk_size)
        self._compression = compression
        self._zstd = zstandard.ZstdCompressor(level=zstd_level)
        self._pool = ThreadPoolExecutor(1) if background else None
        self._tasks = collections.deque()   # the pool's tasks under way
        self._layouts = {}             # (channel ids, payload lengths) -> row layout
        self._schemas = []             # record bytes, in id order
        self._channels = []
        self._close_due = False        # close the chunk at the next later log time
        self._flush_due = False        # and flush the stream then
        self._counts = {}              # channel id -> messages
        self._message_count = 0
        self._t_start = self._t_end = None
        self._chunk_indexes = []       # record bytes
        self._metadata_indexes = []
        self._chunk_count = 0
        # the open chunk: its records, in one buffer (handed whole to the writer when
        # the chunk closes, then replaced), and their length
        self._buf = self._new_buffer(self._chunk_size + (1 << 16))
        self._nbuf = 0
        self._index = {}               # channel id -> array of (log_time, offset) pairs
        self._c_start = self._c_end = None
        self._finished = False
        self._write(MAGIC + _record(OP_HEADER, _string(profile) + _string(library)))

    # ------------------------------------------------------------------ basics
    @property
    def position(self):
        """Return the bytes written to the stream so far (the open chunk not included)."""
        return self._pos

    @property
    def message_count(self):
        """Return the messages added so far (written or in the open chunk)."""
        return self._message_count

    def _write(self, data):
        """Write ``data`` after everything before it (in the background writer, if any)."""
        self._run(self._write_now, data)

    def _write_now(self, data):
        self._out.write(data)
        self._pos += len(data)

    def _run(self, fn, *args):
        """Run ``fn(*args)`` now, or queue it behind the earlier writes (at most 3 under way)."""
        if self._pool is None:
            fn(*args)
            return
        self._tasks.append(self._pool.submit(fn, *args))
        while len(self._tasks) > 3 or (self._tasks and self._tasks[0].done()):
            self._tasks.popleft().result()        # re-raises the writer's OSError

    def _drain(self):
        """Wait until every queued write is done (re-raising its error)."""
        while self._tasks:
            self._tasks.popleft().result()

    @staticmethod
    def _new_buffer(size):
        buf = np.empty(size, dtype=np.uint8)
        return buf, memoryview(buf)

    def _reserve(self, size):
        """Return the open chunk's buffer with room for ``size`` more bytes."""
        buf, view = self._buf
        if self._nbuf + size > len(buf):
            grown = self._new_buffer(max(2 * len(buf), self._nbuf + size))
            grown[0][:self._nbuf] = buf[:self._nbuf]
            self._buf = grown
        return self._buf

    def _append(self, data):
        n = len(data)
        self._reserve(n)[1][self._nbuf:self._nbuf + n] = data
        self._nbuf += n

    def register_schema(self, name, encoding, data):
        """Put a Schema record into the open chunk; return its id (1, 2, ...)."""
        sid = len(self._schemas) + 1
        rec = _record(OP_SCHEMA, struct.pack('<H', sid) + _string(name) + _string(encoding)
                      + _U32.pack(len(data)) + bytes(data))
        self._schemas.append(rec)
        self._append(rec)
        return sid

    def register_channel(self, topic, message_encoding, schema_id, metadata=None):
        """Put a Channel record into the open chunk; return its id (1, 2, ...)."""
        cid = len(self._channels) + 1
        rec = _record(OP_CHANNEL, struct.pack('<HH', cid, schema_id) + _string(topic)
                      + _string(message_encoding) + _string_map(dict(metadata or {})))
        self._channels.append(rec)
        self._counts[cid] = 0
        self._append(rec)
        return cid

    def flush_soon(self):
        """Close the chunk and flush the stream at the next message later than the chunk's."""
        self._close_due = self._flush_due = True

    def _close_before(self, log_time):
        """Close the open chunk if a close is due and ``log_time`` starts a later tick."""
        if self._close_due and self._c_end is not None and log_time > self._c_end:
            flush = self._flush_due
            self.close_chunk()
            if flush:
                self._run(self._out.flush)

    def add_metadata(self, name, data):
        """Write a Metadata record (``{str: str}``) outside any chunk."""
        self._run(self._metadata_now, name, dict(data))

    def _metadata_now(self, name, data):
        rec = _record(OP_METADATA, _string(name) + _string_map(data))
        self._metadata_indexes.append(_record(
            OP_METADATA_INDEX, struct.pack('<QQ', self._pos, len(rec)) + _string(name)))
        self._write_now(rec)

    # ---------------------------------------------------------------- messages
    def add_message(self, channel_id, log_time, data, publish_time, sequence=0):
        """Append one message to the open chunk (closed between ticks once it is full)."""
        if self._close_due:
            self._close_before(log_time)
        idx = self._index.get(channel_id)
        if idx is None:
            if channel_id not in self._counts:
                raise ValueError(f'unknown channel id {channel_id!r}')
            idx = self._index[channel_id] = []
        off = self._nbuf
        rec = _MESSAGE.pack(OP_MESSAGE, 22 + len(data), channel_id, sequence, log_time,
                            publish_time) + data
        self._append(rec)
        idx.append((log_time, off))
        self._counts[channel_id] += 1
        self._message_count += 1
        if self._c_start is None:
            self._c_start = self._c_end = log_time
        elif log_time < self._c_start:
            self._c_start = log_time
        elif log_time > self._c_end:
            self._c_end = log_time
        if self._nbuf >= self._chunk_size:
            self._close_due = True

    def add_rows(self, channel_ids, payloads, log_times, sequences):
        """
        Append ``n`` rows of messages; row ``k`` holds one message per channel, in order.

        ``payloads``: one uint8 array of shape (n, L_j) per channel (fixed-length
        messages), or :class:`~.record_fill.EncodedRows` (encoded as written);
        ``log_times``: one int array (n,) per channel, also used as publish time;
        ``sequences``: one int array (n,) per channel, or the first of n consecutive
        sequence numbers. Rows are never split across
        chunks, and a chunk starts only at a row whose messages are all later
        than everything before it (a tick boundary when a row holds one log time).
        """
        m = len(channel_ids)
        if not (m and len(payloads) == m and len(log_times) == m and len(sequences) == m):
            raise ValueError('channel_ids, payloads, log_times and sequences differ in length')
        for cid in channel_ids:
            if cid not in self._counts:
                raise ValueError(f'unknown channel id {cid!r}')
        n = len(payloads[0])
        if n == 0:
            return
        for p in payloads:
            if len(p) != n or not (isinstance(p, EncodedRows) or p.ndim == 2):
                raise ValueError('payloads must be 2-D arrays or EncodedRows with one row per '
                                 'message')
        layout = self._layout(channel_ids, payloads)
        at = layout.width
        slots, distinct = {}, []        # each distinct log-time array once
        for t in log_times:
            if id(t) not in slots:
                slots[id(t)] = len(distinct)
                distinct.append(np.asarray(t[:n], dtype=np.int64))
        sources = layout.sources(payloads, log_times, sequences, n)
        if len(distinct) == 1:
            row_min = row_max = distinct[0]
        else:
            stacked = np.stack(distinct)
            row_min, row_max = stacked.min(axis=0), stacked.max(axis=0)
        channel_slot = [slots[id(t)] for t in log_times]
        cut_ok = np.empty(n, dtype=bool)        # a chunk may start at row j
        cut_ok[0] = self._c_end is None or int(row_min[0]) > self._c_end
        cut_ok[1:] = row_min[1:] > np.maximum.accumulate(row_max)[:-1]
        cuts = np.flatnonzero(cut_ok)
        starts = np.array(layout.starts, dtype=np.uint64)[:, None]
        k = 0
        while k < n:
            if ((self._close_due or self._nbuf >= self._chunk_size) and cut_ok[k]
                    and self._c_end is not None):
                flush = self._flush_due
                self.close_chunk()
                if flush:
                    self._run(self._out.flush)
            room = max(1, (self._chunk_size - self._nbuf) // at)
            nxt = np.searchsorted(cuts, k + room)       # the rows up to a cut past the room
            r = (int(cuts[nxt]) if nxt < len(cuts) else n) - k
            base = self._nbuf
            block = self._reserve(r * at)[0][base:base + r * at].reshape(r, at)
            layout.scatter(block, k, sources, payloads)
            pairs = np.empty((m, r, 2), dtype=np.uint64)    # (log time, offset) per message
            for u, t in enumerate(distinct):
                pairs[[j for j in range(m) if channel_slot[j] == u], :, 0] = t[k:k + r]
            pairs[:, :, 1] = starts + (base + at * np.arange(r, dtype=np.uint64))
            for j, cid in enumerate(channel_ids):
                self._index.setdefault(cid, []).append(pairs[j])
                self._counts[cid] += r
            lo, hi = int(row_min[k:k + r].min()), int(row_max[k:k + r].max())
            if self._c_start is None:
                self._c_start, self._c_end = lo, hi
            else:
                self._c_start, self._c_end = min(self._c_start, lo), max(self._c_end, hi)
            self._nbuf += block.nbytes
            self._message_count += r * m
            k += r
            if self._nbuf >= self._chunk_size:
                self._close_due = True

    def _layout(self, channel_ids, payloads):
        """Return the :class:`~.record_fill.RowLayout` of rows of these channels and payloads."""
        key = (tuple(channel_ids), tuple(
            (p.template_bytes, p.stamp_offsets, p.offsets) if isinstance(p, EncodedRows)
            else p.shape[1] for p in payloads))
        layout = self._layouts.get(key)
        if layout is None:
            layout = self._layouts[key] = RowLayout(
                [_MESSAGE.pack(OP_MESSAGE, 22 + (p.width if isinstance(p, EncodedRows)
                                                 else p.shape[1]), cid, 0, 0, 0)
                 for cid, p in zip(channel_ids, payloads)],
                [p if isinstance(p, EncodedRows) else p.shape[1] for p in payloads])
        return layout

    def close_chunk(self):
        """Compress and write the open chunk with its message indexes (no-op if empty)."""
        if self._c_start is None:       # no message: the records go out as they are
            if self._nbuf:
                self._write(self._take())
            self._close_due = self._flush_due = False
            return
        size = self._nbuf
        indexes = []                    # (channel id, Message Index record), by channel id
        for cid in sorted(self._index):
            pairs = b''.join(np.asarray(p, dtype='<u8').tobytes()
                             for p in _runs(self._index[cid]))
            indexes.append((cid, _record(OP_MESSAGE_INDEX,
                                         struct.pack('<HI', cid, len(pairs)) + pairs)))
        self._run(self._chunk_now, self._take(), size, indexes, self._c_start, self._c_end)
        self._index = {}
        self._c_start = self._c_end = None
        self._close_due = self._flush_due = False

    def _take(self):
        """Return the open chunk's records (a view of its buffer) and start a new buffer."""
        records = self._buf[1][:self._nbuf]
        self._buf = self._new_buffer(len(self._buf[0]))
        self._nbuf = 0
        return records

    def _chunk_now(self, records, size, indexes, c_start, c_end):
        """
        Write one chunk (compressed here) with its message indexes and index record.

        Run by the writer thread, if any: the CRC, the compression and the writes
        release the GIL, and the Python between them is kept short, since each
        time this thread takes the GIL back the caller's thread waits.
        """
        crc = zlib.crc32(records)
        packed = _compress(self._compression, self._zstd, records, size)
        body = (struct.pack('<QQQI', c_start, c_end, size, crc)
                + _string(self._compression) + struct.pack('<Q', len(packed)))
        start = self._pos
        self._write_now(_PREFIX.pack(OP_CHUNK, len(body) + len(packed)) + body)
        self._write_now(packed)
        chunk_length = self._pos - start
        index_start = self._pos
        offsets, at = {}, index_start
        for cid, rec in indexes:
            offsets[cid] = at
            at += len(rec)
        self._write_now(b''.join(rec for _cid, rec in indexes))
        self._chunk_indexes.append(_record(OP_CHUNK_INDEX, (
            struct.pack('<QQQQ', c_start, c_end, start, chunk_length)
            + _id_map(offsets) + struct.pack('<Q', self._pos - index_start)
            + _string(self._compression)
            + struct.pack('<QQ', len(packed), size))))
        self._chunk_count += 1
        if self._t_start is None:
            self._t_start, self._t_end = c_start, c_end
        else:
            self._t_start = min(self._t_start, c_start)
            self._t_end = max(self._t_end, c_end)

    def flush(self):
        """Write the open chunk and flush the stream (no fsync); wait for the writes."""
        self.close_chunk()
        self._run(self._out.flush)
        self._drain()

    def finish(self):
        """Write the last chunk, Data End, the summary and the footer; flush the stream."""
        if self._finished:
            return
        self.close_chunk()
        self._drain()
        if self._pool is not None:
            self._pool.shutdown()
            self._pool = None
        self._write(_record(OP_DATA_END, _U32.pack(0)))
        summary_start = self._pos
        groups = []
        stats = (struct.pack('<QHIIIIQQ', self._message_count, len(self._schemas),
                             len(self._channels), 0, len(self._metadata_indexes),
                             self._chunk_count, self._t_start or 0, self._t_end or 0)
                 + _id_map(self._counts))
        for opcode, records in ((OP_SCHEMA, self._schemas), (OP_CHANNEL, self._channels),
                                (OP_STATISTICS, [_record(OP_STATISTICS, stats)]),
                                (OP_CHUNK_INDEX, self._chunk_indexes),
                                (OP_METADATA_INDEX, self._metadata_indexes)):
            if records:
                groups.append((opcode, b''.join(records)))
        summary = bytearray()
        offsets = bytearray()
        for opcode, data in groups:
            offsets += _record(OP_SUMMARY_OFFSET, struct.pack(
                '<BQQ', opcode, summary_start + len(summary), len(data)))
            summary += data
        offsets_start = summary_start + len(summary)
        footer_head = (_PREFIX.pack(OP_FOOTER, 20)
                       + struct.pack('<QQ', summary_start, offsets_start))
        crc = zlib.crc32(footer_head, zlib.crc32(bytes(summary) + bytes(offsets)))
        self._write(bytes(summary) + bytes(offsets) + footer_head + _U32.pack(crc) + MAGIC)
        self._out.flush()
        self._finished = True


def _compress(compression, zstd, records, size):
    """Return the chunk's records (a buffer of ``size`` bytes) compressed, or as they are."""
    if compression == 'zstd':
        z = zstd.compressobj(size=size)
        return z.compress(records) + z.flush()
    if compression == 'lz4':
        return lz4.frame.compress(records, compression_level=0, block_linked=False,
                                  content_checksum=False)
    return records


def _runs(pieces):
    """Yield the (log_time, offset) pairs of a channel as arrays, tuples batched."""
    tuples = []
    for p in pieces:
        if isinstance(p, tuple):
            tuples.append(p)
            continue
        if tuples:
            yield np.array(tuples, dtype=np.uint64)
            tuples = []
        yield p
    if tuples:
        yield np.array(tuples, dtype=np.uint64)
