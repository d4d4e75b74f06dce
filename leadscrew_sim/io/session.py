"""
A recording session: MCAP files in a directory, split by size or duration, and recovery.

The session is configured by one :class:`StorageOptions` object, passed whole
(the shape of rosbag2_py's ``StorageOptions``). Each file is an
:class:`leadscrew_sim.io.mcap_file.McapRecorder`; see there for the layout
and the crash-loss bound.
"""
import dataclasses
import math
import os
import re
import time
from pathlib import Path

from ..core.settings import MIN_SPLIT_BYTES, PREFIX_RE
from .mcap_scan import scan
from .mcap_file import Guarded, McapRecorder, one_line_error, ROSBAG2_METADATA_NAME
from .msgdefs import full_type_name, ros2msg_definition, type_hash
from .qos import DEFAULT_QOS


@dataclasses.dataclass(frozen=True)
class StorageOptions:
    """
    Where and how a :class:`RecordingSession` writes, passed whole (rosbag2_py's shape).

    Parameters
    ----------
    directory : str
        Directory of the files; created if missing.
    prefix : str
        File name prefix: 1 to 64 letters, digits, ``_`` or ``-``.
    split_bytes : int
        Start a new file once the current one holds this many bytes [B]; 0 never.
    split_seconds : float
        Start a new file this long after the file's first message [s]; 0 never.
    flush_interval : float
        Write the open chunk and flush at least this often [s] (the crash-loss bound).
    max_total_bytes : int
        Bound of the total size of this prefix's recordings in ``directory`` [B];
        0 none. Before each new file the oldest files named by this session's
        pattern (``<prefix>_<YYYYmmdd-HHMMSS>_<NNN>.mcap``) are deleted until the
        rest fit; no other file is touched. Without ``split_bytes`` the files are
        then split at an eighth of the bound, so that old data can go.

    """

    directory: str
    prefix: str = 'run'
    split_bytes: int = 0
    split_seconds: float = 0.0
    flush_interval: float = 1.0
    max_total_bytes: int = 0

    def __post_init__(self):
        """Check the prefix and the split limits."""
        if not isinstance(self.prefix, str) or not PREFIX_RE.match(self.prefix):
            raise ValueError(f'record_prefix {self.prefix!r} must match {PREFIX_RE.pattern}')
        if not self.split_bytes >= 0 or not self.split_seconds >= 0:
            raise ValueError('split_bytes and split_seconds must be >= 0 (0 = never)')
        if not self.max_total_bytes >= 0:
            raise ValueError('max_total_bytes must be >= 0 (0 = no bound)')

    @classmethod
    def from_run_settings(cls, settings):
        """
        Return the options of a node's run settings (their ``record_*`` fields).

        Parameters
        ----------
        settings : leadscrew_sim.core.settings.RunSettings
            The node's run settings.

        """
        return cls(directory=str(settings.record_dir), prefix=settings.record_prefix,
                   split_bytes=int(settings.record_split_bytes),
                   split_seconds=float(settings.record_split_seconds),
                   flush_interval=float(settings.record_flush_interval),
                   max_total_bytes=int(settings.record_max_total_bytes))

    def to_dict(self):
        """Return the options as a plain dict (JSON for the recorder process)."""
        return dataclasses.asdict(self)


class RecordingSession(Guarded):
    """
    Record into ``options.directory`` as ``<prefix>_<YYYYmmdd-HHMMSS>_<NNN>.mcap`` files.

    A new file starts before a write when the current one holds at least
    ``split_bytes`` bytes or the message's log time is ``split_seconds`` s or
    more after the file's first message (0 = never). Every file is complete on
    its own: it re-registers all channels (same ids) and repeats all metadata.
    A size split happens once the flushed data reach ``split_bytes`` (chunks are
    limited to ``split_bytes / 4``), so a file ends up to one chunk plus its
    summary (schemas, indexes, metadata: a few KiB) above ``split_bytes``.

    Parameters
    ----------
    options : StorageOptions
        Directory, prefix, splitting and flushing.
    metadata : dict, optional
        Record name -> ``{str: str}``, written to each file.

    """

    def __init__(self, options, *, metadata=None):
        """Open the first file."""
        super().__init__()
        if not isinstance(options, StorageOptions):
            raise TypeError(f'options must be StorageOptions, not {type(options).__name__}')
        self.options = options
        self.directory = Path(options.directory)
        self.prefix = options.prefix
        self.split_bytes = int(options.split_bytes)
        self.max_total_bytes = int(options.max_total_bytes)
        if self.max_total_bytes and not self.split_bytes:
            self.split_bytes = max(MIN_SPLIT_BYTES, self.max_total_bytes // 8)
        self.deleted = []        # paths removed to keep within max_total_bytes
        self._latched_ids = set()    # channels with transient local QoS
        self._latched = {}           # their last message: id -> (bytes, publish time)
        self.split_ns = (int(options.split_seconds * 1e9)
                         if math.isfinite(options.split_seconds) else 0)
        self.flush_interval = options.flush_interval
        self._stamp = time.strftime('%Y%m%d-%H%M%S')
        self._index = 0
        self._files = []
        self._channels = []      # (topic, msg_type, qos, trim); id = index + 1
        self._metadata = {}
        self._error = None
        self._done_messages = self._done_bytes = 0
        self._rec = None
        self._file_t0 = None
        self._closed = False
        try:
            self.directory.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            self._error = one_line_error(exc, self.directory)
        for name, data in (metadata or {}).items():
            self._metadata[str(name)] = dict(data)
        self._open_next()

    @property
    def files(self):
        """Return the paths (str) of all files of this session, the current one last."""
        return list(self._files)

    @property
    def current_path(self):
        """Return the path of the file being written, or None."""
        return self._rec.path if self._rec is not None else None

    @property
    def messages_written(self):
        """Return the messages written over all files."""
        return self._done_messages + (self._rec.messages_written if self._rec else 0)

    @property
    def bytes_written(self):
        """Return the bytes written over all files."""
        return self._done_bytes + (self._rec.bytes_written if self._rec else 0)

    @property
    def error(self):
        """Return None or a one-line description of the I/O error that stopped recording."""
        return self._error or (self._rec.error if self._rec is not None else None)

    def _open_next(self):
        if self._error is not None:
            return
        if self.max_total_bytes:
            self._prune()
        root = self.directory.resolve()
        while True:
            path = root / f'{self.prefix}_{self._stamp}_{self._index:03d}.mcap'
            self._index += 1
            if not os.path.lexists(path):
                break
        if path.resolve().parent != root:
            self._error = f'{path}: refusing to write outside {root}'
            return
        chunk = 1 << 20
        if self.split_bytes:
            chunk = max(4096, min(chunk, self.split_bytes // 4))
        rec = McapRecorder(path, flush_interval=self.flush_interval, chunk_size=chunk)
        self._files.append(str(path))
        self._rec, self._file_t0 = rec, None
        for topic, msg_type, qos, trim in self._channels:
            rec.add_channel(topic, msg_type, qos, trim)
        for name, data in self._metadata.items():
            rec.add_metadata(name, data)

    def _prune(self):
        """Delete the oldest recordings of this prefix until the rest leave room for a file."""
        pattern = re.compile(rf'^{re.escape(self.prefix)}_\d{{8}}-\d{{6}}_\d{{3}}\.mcap$')
        try:
            ours = [e for e in os.scandir(self.directory)
                    if pattern.match(e.name) and e.is_file(follow_symlinks=False)]
            ours.sort(key=lambda e: (e.stat().st_mtime_ns, e.name))
            total = sum(e.stat().st_size for e in ours)
            budget = self.max_total_bytes - self.split_bytes
            for e in ours:
                if total <= budget:
                    break
                total -= e.stat().st_size
                os.unlink(e.path)
                self.deleted.append(e.path)
        except OSError as exc:
            self._error = one_line_error(exc, self.directory)

    def _rotate(self):
        rec = self._rec
        rec.close()
        self._done_messages += rec.messages_written
        self._done_bytes += rec.bytes_written
        if rec.error:
            self._error = rec.error
        self._rec = None
        self._open_next()

    def add_channel(self, topic, msg_type, qos=None, trim=True):
        """Register a channel in every file of the session; return its (stable) id."""
        msg_type = full_type_name(msg_type)
        qos = DEFAULT_QOS if qos is None else qos
        with self._op():
            for i, (t, mt, _, _) in enumerate(self._channels):
                if t == topic:
                    if mt != msg_type:
                        raise ValueError(f'topic {topic!r} already recorded as {mt}')
                    return i + 1
            cid = len(self._channels) + 1
            if self._rec is not None:
                got = self._rec.add_channel(topic, msg_type, qos, trim)
                assert got == cid, (got, cid)
            else:
                ros2msg_definition(msg_type)     # same errors as with an open file
            self._channels.append((topic, msg_type, qos, trim))
            if 'transient_local' in qos:
                self._latched_ids.add(cid)
            return cid

    def write(self, channel_id, data, log_time_ns, publish_time_ns=None):
        """Append one serialized message (see :meth:`McapRecorder.write`), splitting first."""
        with self._op():
            if not 1 <= channel_id <= len(self._channels):
                raise ValueError(f'unknown channel id {channel_id!r}')
            if self._rec is None or self._closed:
                return
            rec = self._rec
            if rec.messages_written and (
                    (self.split_bytes and rec.bytes_written >= self.split_bytes)
                    or (self.split_ns and log_time_ns - self._file_t0 >= self.split_ns)):
                self._rotate()
                if self._rec is None:
                    return
                # A latched (transient local) topic's last message starts every new file,
                # so each file holds, e.g., the robot description, as a late subscriber would.
                for cid, (payload, publish) in sorted(self._latched.items()):
                    self._rec.write(cid, payload, log_time_ns, publish)
            if self._file_t0 is None:
                self._file_t0 = int(log_time_ns)
            self._rec.write(channel_id, data, log_time_ns, publish_time_ns)
            if channel_id in self._latched_ids:
                self._latched[channel_id] = (bytes(data), publish_time_ns)

    def flush(self):
        """Write the open chunk of the current file and flush it."""
        with self._op():
            if self._rec is not None:
                self._rec.flush()

    def add_metadata(self, name, data):
        """Write metadata ``name`` to the current file and to every later one."""
        data = {str(k): str(v) for k, v in dict(data).items()}
        with self._op():
            self._metadata[str(name)] = data
            if self._rec is not None:
                self._rec.add_metadata(name, data)

    def _close_now(self):
        if self._closed:
            return
        self._closed = True
        if self._rec is not None:
            self._rec.close()


def recover(src, dst):
    """
    Rewrite an MCAP file cut short (e.g. of a killed recorder) as a complete one.

    Reads ``src`` front to back up to its first record that is not whole
    (:func:`leadscrew_sim.io.mcap_scan.scan`) and writes every whole message,
    with its schema, channel and the metadata records, to ``dst`` with a full
    summary. ``src`` is not changed.

    Parameters
    ----------
    src, dst : str or Path
        The cut file and the repaired copy (a different path).

    Returns
    -------
    Scan
        What was read: its ``messages`` were written; ``end``, ``size`` and
        ``problem`` say where and why the source stops being whole.

    Raises
    ------
    OSError
        If ``src`` cannot be read or ``dst`` cannot be written.
    ValueError
        If ``dst`` is ``src`` or ``src`` is not an MCAP file.

    """
    if os.path.abspath(src) == os.path.abspath(dst):
        raise ValueError('recover() needs a destination different from the source')
    found = scan(src)
    out = McapRecorder(dst, flush_interval=math.inf)
    channels = {}
    for cid, record in found.channels.items():
        schema = found.schemas.get(record.schema_id)
        if schema is None:
            continue
        meta = dict(record.metadata)
        channels[cid] = out._register(
            record.topic, schema.name, schema.encoding, schema.data,
            meta.get('offered_qos_profiles', DEFAULT_QOS), meta)
    for name, data in found.metadata:
        if name != ROSBAG2_METADATA_NAME:
            out.add_metadata(name, data)
    for log_time, cid, data, publish_time, sequence in found.messages:
        if cid in channels:
            out.write(channels[cid], data, log_time, publish_time, _sequence=sequence)
    out.close()
    if out.error:
        raise OSError(out.error)
    found.messages = [m for m in found.messages if m[1] in channels]
    return found


def recover_bag(bag, dst):
    """
    Write a rosbag2 bag (a :class:`~.rosbag2.BagRecording`, messages loaded) as one MCAP file.

    Every whole message of its files (a cut last file up to its last whole
    chunk), in log-time order, with its schema, channel and the metadata
    records, and a full summary. Returns the number of messages written.

    Raises
    ------
    OSError
        If ``dst`` cannot be written.

    """
    out = McapRecorder(dst, flush_interval=math.inf)
    channels = {}
    by_topic = {c.topic: cid for cid, c in bag.channels.items()}
    for cid, record in bag.channels.items():
        schema = bag.schemas.get(record.schema_id)
        if schema is None:
            continue
        data = schema.data
        if not data:            # a sqlite3 bag without its definitions: the installed ones
            try:
                data = ros2msg_definition(full_type_name(schema.name)).encode()
            except LookupError:
                continue
        meta = dict(record.metadata)
        if 'topic_type_hash' not in meta:
            try:
                meta['topic_type_hash'] = type_hash(schema.name)
            except (LookupError, OSError, ValueError):
                meta['topic_type_hash'] = ''
        channels[cid] = out._register(
            record.topic, schema.name, schema.encoding or 'ros2msg', data,
            meta.get('offered_qos_profiles') or DEFAULT_QOS, meta)
    for name, data in bag.metadata:
        if name != ROSBAG2_METADATA_NAME:
            out.add_metadata(name, data)
    n = 0
    for log_time, topic, data in bag.messages:
        cid = by_topic.get(topic)
        if cid in channels:
            out.write(channels[cid], data, log_time, log_time)
            n += 1
    out.close()
    if out.error:
        raise OSError(out.error)
    return n
