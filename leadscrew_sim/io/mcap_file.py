"""
One MCAP file of already-serialized ROS 2 messages, readable by rosbag2 tools.

:class:`McapRecorder` only knows topics, type names and CDR bytes; it never
imports rclpy. Files follow the rosbag2 MCAP layout: profile ``ros2``, one
``ros2msg`` schema per type (:func:`leadscrew_sim.io.msgdefs.ros2msg_definition`),
``cdr`` channels with ``offered_qos_profiles`` metadata, zstd-compressed chunks
with message indexes, a summary with statistics, and a ``rosbag2`` metadata
record (``serialized_metadata``, rosbag2 BagMetadata version 9) written at close.

Loss bound on a crash (SIGKILL, power is not covered: no fsync): the open
chunk is written and the file flushed every ``flush_interval`` seconds of
wall time, checked on each :meth:`McapRecorder.write`, at the first message
of the next tick (so a tick stays in one chunk); :meth:`McapRecorder.flush`
writes at once. A killed process therefore loses at most the messages of
the last ``flush_interval`` s plus one tick and one write period; the rest is
read back by :func:`leadscrew_sim.io.session.recover` or ``mcap recover``.
Times are in nanoseconds, sizes in bytes.
"""
import os
import threading
import time

import numpy as np

from .mcap_writer import McapWriter
from .msgdefs import cdr_length, full_type_name, ros2msg_definition, type_hash
from .qos import DEFAULT_QOS, dump_yaml, qos_list

try:
    from importlib.metadata import version as _version
    LIBRARY = f'leadscrew_sim/{_version("leadscrew_sim")}'
except Exception:  # noqa: B902 - package metadata is optional (source checkout)
    LIBRARY = 'leadscrew_sim'

ROSBAG2_METADATA_VERSION = 9
ROSBAG2_METADATA_NAME = 'rosbag2'


def one_line_error(exc, path):
    """Return an exception as one line that names the file or directory."""
    return f'{path}: {exc.__class__.__name__}: {exc}'.replace('\n', ' ')


class OpGuard:
    """The context manager of :meth:`Guarded._op` (a class: cheaper than a generator)."""

    __slots__ = ('_g',)

    def __init__(self, guarded):
        self._g = guarded

    def __enter__(self):
        g = self._g
        g._lock.acquire()
        g._busy += 1

    def __exit__(self, *exc):
        g = self._g
        g._busy -= 1
        try:
            if not g._busy and g._close_pending:
                g._close_pending = False
                g._close_now()
        finally:
            g._lock.release()
        return False


class Guarded:
    """
    Serialize calls and make ``close()`` safe from a signal handler.

    A ``close()`` that interrupts an operation of the same object (a signal
    handler running mid-``write``) is deferred to the end of that operation.
    """

    def __init__(self):
        self._lock = threading.RLock()
        self._busy = 0
        self._close_pending = False
        self._guard = OpGuard(self)

    def _op(self):
        return self._guard

    def close(self):
        """Finish the file(s); idempotent, never raises on I/O errors."""
        with self._lock:
            if self._busy:
                self._close_pending = True
            else:
                self._close_now()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


class McapRecorder(Guarded):
    """
    Write one rosbag2-compatible MCAP file from serialized (CDR) messages.

    ``flush_interval`` is in seconds of wall time (0 flushes on every write),
    ``chunk_size`` in uncompressed bytes; ``background``: chunks are
    compressed and written by a thread of their own; ``compression``: of the
    chunks (see :class:`McapWriter`). I/O errors (``OSError``: unwritable
    directory, disk full, ...) never escape: they set :attr:`error` to a
    one-line message and stop the recording; data flushed before stays in the
    file and can be read back with :func:`recover`.
    """

    def __init__(self, path, *, flush_interval=1.0, chunk_size=1 << 20, background=False,
                 compression='zstd'):
        super().__init__()
        if not flush_interval >= 0:
            raise ValueError(f'flush_interval must be >= 0 s, not {flush_interval!r}')
        self.path = str(path)
        self.flush_interval = float(flush_interval)
        self.error = None
        self.messages_written = 0
        self._size = 0
        self._closed = False
        self._channels = {}      # id -> dict(topic, type, qos, count)
        self._topic_ids = {}     # topic -> id
        self._schema_ids = {}    # type name -> schema id
        self._t_first = None     # first/last log time, ns
        self._t_last = None
        self._fh = self._writer = None
        self._last_flush = time.monotonic()
        try:
            self._fh = open(self.path, 'wb')
            self._writer = McapWriter(self._fh, profile='ros2', library=LIBRARY,
                                      chunk_size=int(chunk_size), background=background,
                                      compression=compression)
            self._fh.flush()
            self._size = self._writer.position
        except OSError as exc:
            self._fail(exc)

    @property
    def bytes_written(self):
        """Bytes handed to the file so far (the open chunk is not counted)."""
        return self._size

    @property
    def closed(self):
        """Return True once :meth:`close` ran (or an I/O error ended the file)."""
        return self._closed or self._writer is None

    @property
    def channels(self):
        """Return ``{channel_id: (topic, msg_type, qos)}`` of the registered channels."""
        return {cid: (c['topic'], c['type'], c['qos']) for cid, c in self._channels.items()}

    def add_channel(self, topic, msg_type, qos=None, trim=True):
        """
        Register ``topic`` carrying ``msg_type`` (``'pkg/msg/Type'``); return the channel id.

        ``qos`` is an ``offered_qos_profiles`` YAML string (see
        :func:`qos_profile_yaml`); ``None`` means reliable, volatile, keep last 10.
        ``trim=False`` skips the CDR length check of every write, for bytes that
        are known to be exact (``leadscrew_sim.messages`` encoders, DDS raw
        subscriptions); it saves about half of the write cost.
        Registering the same topic and type again returns the same id.
        """
        msg_type = full_type_name(msg_type)
        qos = DEFAULT_QOS if qos is None else qos
        profiles = qos_list(qos)
        if not (profiles and all(isinstance(p, dict) for p in profiles)):
            raise ValueError(f'qos for {topic!r} is not a YAML list of QoS profiles')
        with self._op():
            if topic in self._topic_ids:
                cid = self._topic_ids[topic]
                if self._channels[cid]['type'] != msg_type:
                    raise ValueError(f'topic {topic!r} already recorded as '
                                     f'{self._channels[cid]["type"]}, not {msg_type}')
                return cid
            definition = ros2msg_definition(msg_type)
            return self._register(topic, msg_type, 'ros2msg', definition.encode(), qos,
                                  trim=trim)

    def _register(self, topic, msg_type, schema_encoding, schema_data, qos, metadata=None,
                  trim=False):
        metadata = dict(metadata or {})
        metadata.setdefault('offered_qos_profiles', qos)
        metadata.setdefault('topic_type_hash', type_hash(msg_type) if '/msg/' in msg_type else '')
        cid = len(self._channels) + 1
        self._channels[cid] = {'topic': topic, 'type': msg_type, 'qos': qos, 'count': 0,
                               'trim': trim}
        self._topic_ids[topic] = cid
        if self._writer is None:
            return cid
        try:
            sid = self._schema_ids.get(msg_type)
            if sid is None:
                sid = self._writer.register_schema(msg_type, schema_encoding, schema_data)
                self._schema_ids[msg_type] = sid
            wid = self._writer.register_channel(topic, 'cdr', sid, metadata)
            assert wid == cid, (wid, cid)
        except OSError as exc:
            self._fail(exc)
        return cid

    def write(self, channel_id, data, log_time_ns, publish_time_ns=None, *, _sequence=None):
        """
        Append one serialized message; never raises on I/O errors.

        ``log_time_ns`` is the receive/publish time in ns (uint64, e.g. since the
        epoch or sim time), ``publish_time_ns`` defaults to it. Raises
        ``ValueError`` only for an unknown channel id or a negative time.
        Bytes after the end of the CDR message are dropped (``rmw_serialize``
        of rmw_fastrtps may return a buffer longer than the message, ending in
        uninitialized bytes, which strict readers such as rosbags reject).
        """
        with self._op():
            channel = self._channels.get(channel_id)
            if channel is None:
                raise ValueError(f'unknown channel id {channel_id!r}')
            log_time_ns = int(log_time_ns)
            publish_time_ns = log_time_ns if publish_time_ns is None else int(publish_time_ns)
            if log_time_ns < 0 or publish_time_ns < 0:
                raise ValueError('message times must be >= 0 ns')
            if self._writer is None:
                return
            seq = channel['count'] if _sequence is None else _sequence
            data = bytes(data)
            if channel['trim']:
                end = cdr_length(channel['type'], data)
                if end is not None and end < len(data):
                    data = data[:end]
            try:
                self._writer.add_message(channel_id, log_time_ns, data, publish_time_ns,
                                         sequence=seq & 0xFFFFFFFF)
                channel['count'] += 1
                self.messages_written += 1
                if self._t_first is None:
                    self._t_first = self._t_last = log_time_ns
                elif log_time_ns < self._t_first:
                    self._t_first = log_time_ns
                elif log_time_ns > self._t_last:
                    self._t_last = log_time_ns
                if time.monotonic() - self._last_flush >= self.flush_interval:
                    self._flush_soon_locked()
                self._size = self._writer.position
            except OSError as exc:
                self._fail(exc)

    def write_rows(self, channel_ids, payloads, log_times):
        """
        Append ``n`` rows of fixed-length messages, one per channel and row, in order.

        The bulk form of :meth:`write` for exact CDR bytes (no trimming):
        ``payloads`` is one uint8 array of shape (n, L) per channel,
        ``log_times`` one int array (n,) of ns per channel (publish time =
        log time). Never raises on I/O errors.
        """
        with self._op():
            for cid in channel_ids:
                if cid not in self._channels:
                    raise ValueError(f'unknown channel id {cid!r}')
            if self._writer is None or not len(payloads[0]):
                return
            n = len(payloads[0])
            seqs = [self._channels[c]['count'] for c in channel_ids]
            distinct = {id(t): t for t in log_times}.values()
            lo = min(int(np.min(t)) for t in distinct)
            hi = max(int(np.max(t)) for t in distinct)
            if lo < 0:
                raise ValueError('message times must be >= 0 ns')
            try:
                self._writer.add_rows(channel_ids, payloads, log_times, seqs)
                for c in channel_ids:
                    self._channels[c]['count'] += n
                self.messages_written += n * len(channel_ids)
                self._t_first = lo if self._t_first is None else min(self._t_first, lo)
                self._t_last = hi if self._t_last is None else max(self._t_last, hi)
                if time.monotonic() - self._last_flush >= self.flush_interval:
                    self._flush_soon_locked()
                self._size = self._writer.position
            except OSError as exc:
                self._fail(exc)

    def flush(self):
        """Write the open chunk and flush the file now (no fsync)."""
        with self._op():
            if self._writer is not None:
                try:
                    self._flush_locked()
                except OSError as exc:
                    self._fail(exc)

    def _flush_locked(self):
        self._writer.flush()
        self._size = self._writer.position
        self._last_flush = time.monotonic()

    def _flush_soon_locked(self):
        # the writer closes the chunk and flushes at the next tick (a later log time), so
        # a tick never spans two chunks; the crash-loss bound grows by that one tick
        self._writer.flush_soon()
        self._last_flush = time.monotonic()

    def add_metadata(self, name, data):
        """Write a metadata record ``name`` with string keys and values (``str()`` applied)."""
        if name == ROSBAG2_METADATA_NAME:
            raise ValueError(f'metadata name {name!r} is reserved for the recorder')
        data = {str(k): str(v) for k, v in dict(data).items()}
        with self._op():
            if self._writer is None:
                return
            try:
                self._writer.add_metadata(str(name), data)
                self._fh.flush()
                self._size = self._writer.position
            except OSError as exc:
                self._fail(exc)

    def bag_metadata(self):
        """Return the rosbag2 BagMetadata (version 9) of this file as a dict."""
        count = self.messages_written
        start = self._t_first or 0
        duration = (self._t_last - self._t_first) if count else 0
        name = os.path.basename(self.path)
        topics = [{'topic_metadata': {
            'name': c['topic'], 'type': c['type'], 'serialization_format': 'cdr',
            'offered_qos_profiles': qos_list(c['qos']),
            'type_description_hash': type_hash(c['type']) if '/msg/' in c['type'] else ''},
            'message_count': c['count']} for c in self._channels.values()]
        return {
            'version': ROSBAG2_METADATA_VERSION, 'storage_identifier': 'mcap',
            'duration': {'nanoseconds': duration},
            'starting_time': {'nanoseconds_since_epoch': start},
            'message_count': count, 'topics_with_message_count': topics,
            'compression_format': '', 'compression_mode': '',
            'relative_file_paths': [name],
            'files': [{'path': name, 'starting_time': {'nanoseconds_since_epoch': start},
                       'duration': {'nanoseconds': duration}, 'message_count': count}],
            'custom_data': {}, 'ros_distro': os.environ.get('ROS_DISTRO') or 'jazzy'}

    def _close_now(self):
        if self._closed:
            return
        self._closed = True
        if self._writer is None:
            return
        try:
            self._writer.add_metadata(ROSBAG2_METADATA_NAME,
                                      {'serialized_metadata': dump_yaml(self.bag_metadata())})
            self._writer.finish()
            self._size = self._writer.position
            self._fh.close()
        except OSError as exc:
            self._fail(exc)
        self._writer = None

    def _fail(self, exc):
        if self.error is None:
            self.error = one_line_error(exc, self.path)
        self._writer = None
        if self._fh is not None:
            try:
                self._fh.close()
            except OSError:
                pass
