"""
Reading a whole MCAP file: header, channels, metadata and messages, with one-line errors.

Any ros2-profile file is read; :meth:`Recording.require_ours` tells a
leadscrew_sim run file (:mod:`.run_file`) from others.
"""
from concurrent.futures import ThreadPoolExecutor
import os
import struct
import types
import zlib

import lz4.frame
from mcap.reader import make_reader
import numpy as np
import zstandard

from .mcap_scan import MAX_CHUNK_BYTES, scan
from .mcap_writer import MAGIC
from .run_file import PARAMS_RECORD
from .topics import graph_name, TOPIC_SPECS
from ..core.errors import LeadscrewError

__all__ = ['Recording', 'RecordingError', 'TopicArrays']


def _detail(exc):
    """Return the first line of an exception's message (or its class name)."""
    return str(exc).splitlines()[0] if str(exc) else exc.__class__.__name__


class _Bounded:
    """
    A binary file whose reads never ask for more than the bytes that remain.

    A corrupt length field then costs at most the file's size in memory,
    never the length it claims.
    """

    def __init__(self, fh):
        """Wrap the open file ``fh``."""
        self._fh = fh
        self._size = os.fstat(fh.fileno()).st_size

    def read(self, n=-1):
        """Read at most ``n`` bytes, and never past the end of the file."""
        rest = max(0, self._size - self._fh.tell())
        return self._fh.read(rest if n is None or n < 0 else min(n, rest))

    def __getattr__(self, name):
        """Everything else as the file does."""
        return getattr(self._fh, name)


class RecordingError(LeadscrewError, ValueError):
    """A file that is missing, not MCAP, truncated, corrupt or of the wrong kind."""


class Recording:
    """
    A fully read MCAP file: header, channels, metadata and the messages in log-time order.

    ``messages`` holds ``(log_time [ns], topic, data)``; messages of one log
    time keep their file order. A file cut short by a crash (no summary, an
    incomplete last record) or damaged after some point is read up to its
    last whole chunk: :attr:`cut` then says where it stops and what was read
    (empty for a whole file), and :attr:`summary` is None.

    Parameters
    ----------
    path : str or Path
        The MCAP file.
    topics : list of str, optional
        Read only the messages of these topics.
    load_messages : bool
        Read the messages (else only header, summary and metadata).

    """

    def __init__(self, path, topics=None, load_messages=True):
        """Read ``path``; raise RecordingError for missing, non-MCAP or unreadable files."""
        self.path = str(path)
        try:
            fh = open(self.path, 'rb')
        except FileNotFoundError:
            raise RecordingError(f'{self.path}: no such file') from None
        except OSError as exc:
            raise RecordingError(f'{self.path}: {exc.strerror or exc}') from None
        with fh:
            if fh.read(8) != MAGIC:
                raise RecordingError(f'{self.path}: not an MCAP file (bad magic bytes)')
            fh.seek(0)
            self.cut = ''
            try:
                self._read(_Bounded(fh), topics, load_messages)
            except Exception as exc:  # noqa: B902 - mcap raises many kinds on bad data
                self._read_cut(topics, load_messages, _detail(exc))
        self.profile = self.header.profile
        self.topic_types = {c.topic: self.schemas[c.schema_id].name if c.schema_id in
                            self.schemas else '' for c in self.channels.values()}

    def load(self, topics=None):
        """
        Read the messages (of ``topics`` only, if given) of a file opened without them.

        Parameters
        ----------
        topics : list of str, optional
            The topics to read.

        """
        if self.cut:
            self._read_cut(topics, True, self.cut)
            return
        try:
            with open(self.path, 'rb') as fh:
                self._read(_Bounded(fh), topics, True)
        except OSError as exc:
            raise RecordingError(f'{self.path}: {exc.strerror or exc}') from None
        except Exception as exc:  # noqa: B902 - mcap raises many kinds on bad data
            raise RecordingError(f'{self.path}: truncated or corrupt MCAP file '
                                 f'({_detail(exc)})') from None

    def topic_arrays(self, topics):
        """
        Read the messages of ``topics`` as arrays, through the chunks' message indexes.

        Returns ``{topic: TopicArrays}`` (every topic asked for, empty when it
        has no message), or None when the file has no chunk or message index
        (then read :attr:`messages`). Loads nothing into :attr:`messages`.

        Parameters
        ----------
        topics : list of str
            Recorded topic names.

        """
        if self.summary is None:
            return None
        try:
            with open(self.path, 'rb') as fh:
                return _topic_arrays(_Bounded(fh), self.summary, topics)
        except OSError as exc:
            raise RecordingError(f'{self.path}: {exc.strerror or exc}') from None
        except (ValueError, struct.error, zstandard.ZstdError, RuntimeError) as exc:
            raise RecordingError(f'{self.path}: truncated or corrupt MCAP file ({exc})') \
                from None

    def _read(self, fh, topics, load_messages):
        """Read header, summary, metadata and (optionally) the messages of ``fh``."""
        reader = make_reader(fh, validate_crcs=True)
        self.header = reader.get_header()
        summary = reader.get_summary()
        if summary is None:
            raise ValueError('no summary section')
        self.summary = summary
        self.metadata = [(m.name, dict(m.metadata)) for m in reader.iter_metadata()]
        self.channels = {c.id: c for c in summary.channels.values()}
        self.schemas = {s.id: s for s in summary.schemas.values()}
        self.messages = []
        if load_messages:
            want = set(topics) if topics else None
            msgs = self.messages
            if summary.chunk_indexes:
                _read_chunks(fh, summary, want, msgs)
            else:
                for _schema, channel, msg in reader.iter_messages(topics=topics,
                                                                  log_time_order=False):
                    if want is None or channel.topic in want:
                        msgs.append((msg.log_time, channel.topic, msg.data))
            msgs.sort(key=_log_time)        # stable: ties keep file order

    def _read_cut(self, topics, load_messages, why):
        """
        Read a file without a readable summary front to back, up to its last whole chunk.

        Sets :attr:`cut` to where the file stops being whole and what was read
        (:attr:`summary` is None); raises RecordingError when nothing whole is left.
        """
        try:
            found = scan(self.path)
        except (OSError, ValueError) as exc:
            raise RecordingError(f'{self.path}: {exc}') from None
        if found.header is None or not found.channels:
            raise RecordingError(f'{self.path}: truncated or corrupt MCAP file, nothing whole '
                                 f'to read ({found.problem or why})')
        self.header, self.summary = found.header, None
        self.metadata = list(found.metadata)
        self.channels, self.schemas = dict(found.channels), dict(found.schemas)
        self.messages = []
        if load_messages:
            want = set(topics) if topics else None
            topic_of = {cid: c.topic for cid, c in found.channels.items()}
            self.messages = [(m[0], topic_of[m[1]], m[2]) for m in found.messages
                             if m[1] in topic_of and (want is None or topic_of[m[1]] in want)]
            self.messages.sort(key=_log_time)
        times = [m[0] for m in found.messages]
        span = (f', log time {min(times) / 1e9:.3f} .. {max(times) / 1e9:.3f} s'
                if times else '')
        self.cut = (f'{found.problem or "its summary is unreadable"}; read '
                    f'{len(found.messages)} messages{span}, up to byte {found.end} of '
                    f'{found.size}')

    def statistics(self):
        """
        Return the summary's Statistics record, or for a cut file the same figures of its messages.

        The figures used are ``message_count``, ``message_start_time``,
        ``message_end_time`` [ns] and ``channel_message_counts`` (channel id -> count).
        """
        if self.summary is not None:
            return self.summary.statistics
        cid = {c.topic: i for i, c in self.channels.items()}
        counts = {}
        for _t, topic, _d in self.messages:
            counts[cid[topic]] = counts.get(cid[topic], 0) + 1
        times = [m[0] for m in self.messages]
        return types.SimpleNamespace(
            message_count=len(times), message_start_time=min(times, default=0),
            message_end_time=max(times, default=0), channel_message_counts=counts)

    def record(self, name):
        """Return the first metadata record called ``name`` (or None)."""
        for n, data in self.metadata:
            if n == name:
                return data
        return None

    def require_ros2(self):
        """Raise RecordingError unless the header profile is ros2."""
        if self.profile != 'ros2':
            raise RecordingError(f'{self.path}: not a ROS 2 recording (MCAP profile '
                                 f'{self.profile!r}, expected "ros2")')

    def require_ours(self, what):
        """Raise RecordingError unless the file is a leadscrew_sim recording; ``what`` needs it."""
        self.require_ros2()
        if self.record(PARAMS_RECORD) is None:
            raise RecordingError(f'{self.path}: {what} needs a leadscrew_sim recording (no '
                                 f'"{PARAMS_RECORD}" metadata record)')

    def role_topic(self, rel):
        """
        Return the recorded topic that is relative topic ``rel`` in some namespace (or None).

        ``joint_states`` is not ``sim/joint_states``: a topic that ends with a
        longer name of the topic table ending in ``rel`` belongs to that one.
        """
        longer = [k for k in TOPIC_SPECS if k != rel and k.endswith('/' + rel)]
        found = [topic for topic in self.topic_types
                 if (topic == rel or topic.endswith('/' + rel)) and not any(
                     topic == '/' + k or topic.endswith('/' + k) for k in longer)]
        ours = '/' + graph_name(rel)        # the node's own name first (axis/joint_states)
        for topic in found:
            if topic.endswith(ours):
                return topic
        return found[0] if found else None


def _log_time(message):
    return message[0]


class TopicArrays:
    """
    The messages of one topic: ``log_times`` [ns] (int64), ``ranks`` and ``data``.

    ``ranks``: 1 + the number of messages of any topic with the same log time
    before it in the file; ``data``: a uint8 array (n, L) when every message
    has L bytes, else a list of bytes. In file order.
    """

    __slots__ = ('log_times', 'ranks', 'data')

    def __init__(self, log_times, ranks, data):
        """Keep the arrays."""
        self.log_times, self.ranks, self.data = log_times, ranks, data

    def messages(self):
        """Return the payloads as a list of bytes."""
        if isinstance(self.data, list):
            return self.data
        n, width = self.data.shape
        blob = self.data.tobytes()
        return [blob[i:i + width] for i in range(0, n * width, width)]


_CHUNK_HEAD = struct.Struct('<BQQQQI')      # opcode, length, start, end, size, crc
_U32 = struct.Struct('<I')
_U64 = struct.Struct('<Q')
_MESSAGE_HEAD = struct.Struct('<BQHIQ')     # opcode, length, channel, sequence, log time


def _read_chunks(fh, summary, want, msgs):
    """
    Append (log_time, topic, data) of the messages of every chunk, in file order.

    The chunks are found through the summary's chunk indexes, decompressed
    (zstd, lz4 or none) and checked against their CRC; the message records
    are walked with struct, which is many times faster than the record
    objects of the mcap reader. Raises ValueError on a corrupt chunk.
    """
    topic_of = {cid: c.topic for cid, c in summary.channels.items()
                if want is None or c.topic in want}
    zstd = zstandard.ZstdDecompressor()
    unpack_head = _MESSAGE_HEAD.unpack_from
    for index in sorted(summary.chunk_indexes, key=lambda c: c.chunk_start_offset):
        data = _chunk_records(fh, index, zstd)
        pos, end = 0, len(data)
        while pos < end:
            op, length, channel, _seq, log_time = unpack_head(data, pos)
            if op == 0x05:
                topic = topic_of.get(channel)
                if topic is not None:
                    msgs.append((log_time, topic, data[pos + 31:pos + 9 + length]))
            pos += 9 + length


def _chunk_records(fh, index, zstd):
    """Return the decompressed records of the chunk of a chunk index, CRC checked."""
    return _decoded(_chunk_bytes(fh, index), index, zstd)


def _chunk_bytes(fh, index):
    """Return the bytes of the Chunk record of a chunk index, as stored."""
    fh.seek(index.chunk_start_offset)
    return fh.read(index.chunk_length)


def _decoded(raw, index, zstd):
    """Return the decompressed records of a Chunk record's bytes, CRC checked."""
    if len(raw) != index.chunk_length or raw[0] != 0x06:
        raise ValueError(f'no chunk at offset {index.chunk_start_offset}')
    _op, _length, _start, _end, size, crc = _CHUNK_HEAD.unpack_from(raw, 0)
    at = _CHUNK_HEAD.size
    n = _U32.unpack_from(raw, at)[0]
    compression = raw[at + 4:at + 4 + n].decode()
    at += 4 + n
    n = _U64.unpack_from(raw, at)[0]
    packed = memoryview(raw)[at + 8:at + 8 + n]
    if size > MAX_CHUNK_BYTES:
        raise ValueError(f'chunk at offset {index.chunk_start_offset}: {size} B uncompressed '
                         f'exceeds the bound of {MAX_CHUNK_BYTES} B')
    if compression == 'zstd':
        data = zstd.decompress(packed, max_output_size=size)
    elif compression == 'lz4':
        data = lz4.frame.LZ4FrameDecompressor().decompress(packed, max_length=size)
    elif compression == '':
        data = bytes(packed)
    else:
        raise ValueError(f'unknown chunk compression {compression!r}')
    if len(data) != size or (crc and zlib.crc32(data) != crc):
        raise ValueError(f'chunk at offset {index.chunk_start_offset}: bad size or CRC')
    return data


def _message_indexes(fh, index):
    """Return {channel id: (log times, offsets)} of a chunk's Message Index records."""
    out = {}
    if not index.message_index_offsets:
        return out
    start = min(index.message_index_offsets.values())
    fh.seek(start)
    raw = fh.read(index.message_index_length)
    for cid, off in index.message_index_offsets.items():
        at = off - start
        if raw[at] != 0x07:
            raise ValueError(f'no message index at offset {off}')
        n = _U32.unpack_from(raw, at + 11)[0]
        pairs = np.frombuffer(raw, dtype='<u8', count=n // 8, offset=at + 15).reshape(-1, 2)
        out[cid] = pairs
    return out


def _gather(buf, starts, width):
    """
    Return the rows ``buf[s:s + width]`` of the increasing ``starts``: uint8 (n, width).

    Records written as rows lie at one stride; each run of one stride is one
    strided view, and the views are copied out together.
    """
    return np.concatenate(_strided_views(buf, starts, width))


def _strided_views(buf, starts, width):
    """Return the rows ``buf[s:s + width]`` of the increasing ``starts`` as strided views."""
    n = len(starts)
    step = np.diff(starts)
    changes = np.flatnonzero(step[1:] != step[:-1]) + 1     # where a new stride begins
    if len(changes) > n // 16:      # interleaved records (another writer's): one gather
        starts = np.asarray(starts, dtype=np.int64)
        return [buf[starts[:, None] + np.arange(width)]]
    parts, i = [], 0
    while i < n:
        if i == n - 1:
            parts.append(buf[int(starts[i]):int(starts[i]) + width][None, :])
            break
        at = np.searchsorted(changes, i, side='right')
        j = int(changes[at]) if at < len(changes) else n - 1   # the run's last start
        parts.append(np.lib.stride_tricks.as_strided(
            buf[int(starts[i]):], shape=(j - i + 1, width), strides=(int(step[i]), 1),
            writeable=False))
        i = j + 1
    return parts


def _chunk_arrays(fh, number, index, records, want, all_times, all_keys, parts, count):
    """
    Add the messages of chunk ``number`` to the per-channel ``parts``; return the count.

    ``records``: the future of its decompressed records (None: it holds no wanted
    channel); ``all_times`` and
    ``all_keys`` get the log time and file-order key of each of its messages.
    """
    pairs = _message_indexes(fh, index)
    starts = {}
    for cid, p in pairs.items():
        all_times.append(p[:, 0].astype(np.int64))
        all_keys.append((number << 40) + p[:, 1].astype(np.int64))
        starts[cid] = count
        count += len(p)
    wanted = [cid for cid in pairs if cid in want and len(pairs[cid])]
    if not wanted:
        return count
    buf = np.frombuffer(records.result(), dtype=np.uint8)
    for cid in wanted:
        off = pairs[cid][:, 1].astype(np.int64)
        lengths = _gather(buf, off + 1, 8).view('<u8').ravel()        # record lengths
        size = lengths - 22
        if len(size) and (size == size[0]).all():     # views, copied out once at the end
            data = _strided_views(buf, off + 31, int(size[0]))
        else:
            data = [buf[o + 31:o + 9 + int(n)].tobytes() for o, n in zip(off, lengths)]
        parts[cid].append((pairs[cid][:, 0].astype(np.int64), (number << 40) + off, data,
                           starts[cid]))
    return count


def _topic_arrays(fh, summary, topics):
    """Read ``topics`` through the message indexes (see Recording.topic_arrays)."""
    indexes = sorted(summary.chunk_indexes, key=lambda c: c.chunk_start_offset)
    if not indexes or any(not c.message_index_offsets and c.message_index_length
                          for c in indexes):
        return None
    want = {cid: c.topic for cid, c in summary.channels.items() if c.topic in set(topics)}
    zstd = zstandard.ZstdDecompressor()
    all_times, all_keys = [], []               # every message: log time, file order key
    parts = {cid: [] for cid in want}          # (times, keys, data, start in all) per chunk
    count = 0
    # a thread decompresses and checks the next chunks that hold a wanted channel (both
    # release the GIL) while this one takes the messages of the current one apart
    needed = [number for number, index in enumerate(indexes)
              if any(cid in want for cid in index.message_index_offsets)]
    with ThreadPoolExecutor(1) as pool:
        futures = {}

        def prefetch(upto):
            while needed and needed[0] <= upto:
                n = needed.pop(0)
                futures[n] = pool.submit(_decoded, _chunk_bytes(fh, indexes[n]), indexes[n],
                                         zstd)
        for number, index in enumerate(indexes):
            prefetch(number + 2)
            count = _chunk_arrays(fh, number, index, futures.pop(number, None), want,
                                  all_times, all_keys, parts, count)
    times = np.concatenate(all_times) if all_times else np.zeros(0, np.int64)
    keys = np.concatenate(all_keys) if all_keys else np.zeros(0, np.int64)
    order = np.lexsort((keys, times))             # log time, then file order
    sorted_times = times[order]
    at = np.arange(len(order))
    new_time = np.ones(len(order), dtype=bool)      # the first message of its log time
    new_time[1:] = sorted_times[1:] != sorted_times[:-1]
    first = np.maximum.accumulate(np.where(new_time, at, 0))
    rank_all = np.empty(len(order), dtype=np.int64)
    rank_all[order] = at - first + 1
    out = {topic: TopicArrays(np.zeros(0, np.int64), np.zeros(0, np.int64), [])
           for topic in topics}
    for cid, chunks in parts.items():
        if not chunks:
            continue
        t = np.concatenate([c[0] for c in chunks])
        k = np.concatenate([c[1] for c in chunks])
        views = all(isinstance(c[2], list) and c[2] and isinstance(c[2][0], np.ndarray)
                    for c in chunks)
        if views and len({v.shape[1] for c in chunks for v in c[2]}) == 1:
            data = np.concatenate([v for c in chunks for v in c[2]])
        else:
            data = [m for c in chunks for m in (
                c[2] if not (c[2] and isinstance(c[2][0], np.ndarray)) else
                TopicArrays(None, None, np.concatenate(c[2])).messages())]
        ranks = np.concatenate([rank_all[c[3]:c[3] + len(c[0])] for c in chunks])
        if not (k[1:] > k[:-1]).all():           # the index lists its messages out of order
            o = np.argsort(k, kind='stable')    # file order
            data = data[o] if isinstance(data, np.ndarray) else [data[i] for i in o]
            t, ranks = t[o], ranks[o]
        out[want[cid]] = TopicArrays(t, ranks, data)
    return out
