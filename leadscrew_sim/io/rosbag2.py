"""
Reading a rosbag2 bag: a directory with ``metadata.yaml`` and its split files, as one recording.

``ros2 bag record`` leaves a directory: ``metadata.yaml`` (storage,
compression, the files in order) and one or more storage files. A
:class:`BagRecording` reads them all and offers what a
:class:`~leadscrew_sim.io.mcap_reader.Recording` of one MCAP file offers: the
channels by topic (one per topic over all files), the metadata records and
the messages merged in log-time order, and :meth:`topic_arrays` through the
chunk indexes of each file.

- MCAP storage: each file is read as one MCAP file (lz4, zstd or no chunk
  compression); a last file cut by a crash is read up to its last whole chunk.
- sqlite3 storage (``.db3``): the ``topics`` and ``messages`` tables, by
  timestamp.
- rosbag2's own compression (``compression_mode`` ``file`` or ``message``)
  is refused in one line: the files must be decompressed first.
- A bag without ``metadata.yaml`` (its recorder did not close) is read from
  its ``.mcap`` files in name order, and says so in :attr:`cut`.
"""
import os
from pathlib import Path
import re
import sqlite3
import types

from mcap.records import Channel, Header, Schema
import numpy as np
import yaml

from .mcap_reader import Recording, RecordingError, TopicArrays

__all__ = ['BagRecording', 'is_bag', 'METADATA_FILE']

#: The file of a rosbag2 bag that lists its storage and its files.
METADATA_FILE = 'metadata.yaml'

#: The storage plugins read (``storage_identifier`` of metadata.yaml).
STORAGES = ('mcap', 'sqlite3')


def is_bag(path):
    """Return whether ``path`` is a directory (a rosbag2 bag, or meant as one)."""
    return os.path.isdir(path)


def _natural(name):
    """Sort key of a file name: its digit runs as numbers (bag_2 before bag_10)."""
    return [int(p) if p.isdigit() else p for p in re.split(r'(\d+)', name)]


def read_metadata(path):
    """
    Return the ``rosbag2_bagfile_information`` of a bag's metadata.yaml (None without one).

    Raises RecordingError for unreadable YAML or a file without that section.
    """
    meta = Path(path) / METADATA_FILE
    if not meta.is_file():
        return None
    try:
        info = yaml.safe_load(meta.read_text(encoding='utf-8'))
    except (OSError, UnicodeDecodeError, yaml.YAMLError) as exc:
        raise RecordingError(f'{meta}: unreadable ({str(exc).splitlines()[0]})') from None
    info = info.get('rosbag2_bagfile_information') if isinstance(info, dict) else None
    if not isinstance(info, dict):
        raise RecordingError(f'{meta}: no rosbag2_bagfile_information section')
    return info


def bag_files(path, info):
    """
    Return (storage identifier, [file paths in order], note) of a bag.

    Refuses rosbag2's file- and message-level compression and unknown storages.
    """
    path = Path(path)
    if info is None:
        files = sorted((p for p in path.iterdir() if p.suffix == '.mcap'),
                       key=lambda p: _natural(p.name))
        if not files:
            db3 = sorted(p.name for p in path.iterdir() if p.suffix == '.db3')
            if db3:
                files = [path / n for n in db3]
                return 'sqlite3', files, f'no {METADATA_FILE}: read the .db3 files in name order'
            raise RecordingError(f'{path}: not a rosbag2 bag (no {METADATA_FILE} and no .mcap '
                                 'or .db3 files)')
        return 'mcap', files, f'no {METADATA_FILE} (its recorder did not close): read the ' \
            f'{len(files)} .mcap files in name order'
    mode = str(info.get('compression_mode') or '').lower()
    fmt = str(info.get('compression_format') or '')
    if mode not in ('', 'none'):
        raise RecordingError(
            f'{path}: rosbag2 {mode}-level compression ({fmt or "?"}, compression_mode '
            f'{mode.upper()}) is not read; decompress the bag first (ros2 bag convert, or '
            f'`{fmt or "zstd"} -d` on each file and the metadata without compression)')
    storage = str(info.get('storage_identifier') or 'mcap')
    if storage not in STORAGES:
        raise RecordingError(f'{path}: storage_identifier {storage!r} is not read (read: '
                             f'{", ".join(STORAGES)})')
    names = info.get('relative_file_paths') or []
    if not isinstance(names, list) or not names:
        raise RecordingError(f'{path}/{METADATA_FILE}: no relative_file_paths')
    files = [path / str(n) for n in names]
    missing = [str(f) for f in files if not f.is_file()]
    if missing:
        raise RecordingError(f'{path}: the split file {missing[0]} that {METADATA_FILE} '
                             f'lists is not there ({len(files)} listed)')
    return storage, files, ''


class BagRecording(Recording):
    """
    A rosbag2 bag read as one recording: its split files merged in log-time order.

    The attributes are those of :class:`Recording`: ``header`` (of the first
    file), ``schemas`` and ``channels`` (one per type and topic, ids of this
    bag), ``metadata`` (every file's records, repeated ones once),
    ``messages`` (stable by log time: ties keep file order), ``topic_types``
    and ``cut`` (where a cut file stops, and a bag without metadata.yaml).
    ``summary`` is None unless every file has one; :meth:`topic_arrays` reads
    the files through their chunk indexes either way. ``files`` lists the
    storage files in order, ``storage`` is ``mcap`` or ``sqlite3``.

    Parameters
    ----------
    path : str or Path
        The bag directory.
    topics : list of str, optional
        Read only the messages of these topics.
    load_messages : bool
        Read the messages (else only header, channels and metadata).

    """

    def __init__(self, path, topics=None, load_messages=True):
        """Read the bag's metadata.yaml and its files; raise RecordingError for bad bags."""
        self.path = str(path)
        if not os.path.isdir(self.path):
            raise RecordingError(f'{self.path}: no such bag directory')
        try:
            self.info = read_metadata(self.path)
            self.storage, self.files, note = bag_files(self.path, self.info)
        except OSError as exc:
            raise RecordingError(f'{self.path}: {exc.strerror or exc}') from None
        reader = Recording if self.storage == 'mcap' else _Db3File
        self.parts = [reader(f, topics=topics, load_messages=load_messages) for f in self.files]
        cuts = [f'{p.path}: {p.cut}' for p in self.parts if p.cut]
        self.cut = '; '.join(([note] if note else []) + cuts)
        self._merge_records()
        self.messages = []
        if load_messages:
            self.messages = self._merged_messages()
        self.summary = None if any(p.summary is None for p in self.parts) else True

    def _merge_records(self):
        """Make one schema per type and one channel per topic; collect the metadata."""
        first = self.parts[0]
        self.header = first.header
        self.profile = first.header.profile
        self.schemas, self.channels, self.metadata = {}, {}, []
        by_name, by_topic = {}, {}
        self._ids = []              # per part: its channel id -> this bag's
        for part in self.parts:
            ids = {}
            for cid, ch in sorted(part.channels.items()):
                schema = part.schemas.get(ch.schema_id)
                name = schema.name if schema is not None else ''
                if schema is not None and name not in by_name:
                    sid = len(by_name) + 1
                    by_name[name] = sid
                    self.schemas[sid] = Schema(id=sid, name=name, encoding=schema.encoding,
                                               data=schema.data)
                if ch.topic not in by_topic:
                    new = len(by_topic) + 1
                    by_topic[ch.topic] = new
                    self.channels[new] = Channel(
                        id=new, topic=ch.topic, message_encoding=ch.message_encoding,
                        metadata=dict(ch.metadata), schema_id=by_name.get(name, 0))
                ids[cid] = by_topic[ch.topic]
            self._ids.append(ids)
            for item in part.metadata:
                if item not in self.metadata:
                    self.metadata.append(item)
        self.topic_types = {c.topic: self.schemas[c.schema_id].name if c.schema_id in
                            self.schemas else '' for c in self.channels.values()}

    def _merged_messages(self):
        """Return the messages of every part, stable by log time (ties: file order)."""
        if len(self.parts) == 1:
            return self.parts[0].messages
        msgs = [m for p in self.parts for m in p.messages]
        msgs.sort(key=_log_time)
        return msgs

    def load(self, topics=None):
        """Read the messages (of ``topics`` only, if given) of a bag opened without them."""
        for part in self.parts:
            part.load(topics)
        self.messages = self._merged_messages()

    def topic_arrays(self, topics):
        """
        Read the messages of ``topics`` as arrays, through each file's chunk indexes.

        Returns ``{topic: TopicArrays}`` in log-time order (ties: file order);
        a file without indexes (a cut one) contributes its messages as read.
        ``ranks`` count within one file's log time.
        """
        per_part = []
        for part in self.parts:
            got = part.topic_arrays(topics)
            if got is None:
                if not part.messages:
                    part.load(topics)
                got = _arrays_of(part.messages, topics)
            per_part.append(got)
        out = {}
        for topic in topics:
            pieces = [g[topic] for g in per_part if len(g[topic].log_times)]
            if not pieces:
                out[topic] = TopicArrays(np.zeros(0, np.int64), np.zeros(0, np.int64), [])
                continue
            if len(pieces) == 1:
                out[topic] = pieces[0]
                continue
            t = np.concatenate([p.log_times for p in pieces])
            r = np.concatenate([p.ranks for p in pieces])
            rows = [p.data for p in pieces]
            if all(isinstance(d, np.ndarray) for d in rows) and \
                    len({d.shape[1] for d in rows}) == 1:
                data = np.concatenate(rows)
            else:
                data = [m for p in pieces for m in p.messages()]
            o = np.argsort(t, kind='stable')
            if (np.diff(o) != 1).any():
                t, r = t[o], r[o]
                data = data[o] if isinstance(data, np.ndarray) else [data[i] for i in o]
            out[topic] = TopicArrays(t, r, data)
        return out

    def statistics(self):
        """Return message_count, message_start/end_time [ns] and channel_message_counts."""
        counts, start, end, total = {}, [], [], 0
        for part, ids in zip(self.parts, self._ids):
            st = part.statistics()
            if st is None or not st.message_count:
                continue
            total += st.message_count
            start.append(st.message_start_time)
            end.append(st.message_end_time)
            for cid, n in dict(st.channel_message_counts).items():
                if cid in ids:
                    counts[ids[cid]] = counts.get(ids[cid], 0) + n
        return types.SimpleNamespace(
            message_count=total, message_start_time=min(start, default=0),
            message_end_time=max(end, default=0), channel_message_counts=counts)

    def size(self):
        """Return the bytes of the bag's storage files [B]."""
        return sum(os.path.getsize(f) for f in self.files)


def _log_time(message):
    return message[0]


def _arrays_of(messages, topics):
    """Return {topic: TopicArrays} of (log time, topic, data) messages (ranks by log time)."""
    want = set(topics)
    got = {t: ([], [], []) for t in topics}
    same, rank = None, 0
    for log_time, topic, data in messages:
        if log_time != same:
            same, rank = log_time, 0
        rank += 1
        if topic in want:
            g = got[topic]
            g[0].append(log_time)
            g[1].append(rank)
            g[2].append(data)
    return {t: TopicArrays(np.array(g[0], dtype=np.int64), np.array(g[1], dtype=np.int64),
                           g[2]) for t, g in got.items()}


class _Db3File:
    """
    One sqlite3 storage file of a bag, offered as a :class:`Recording` without a summary.

    The ``topics`` table gives the channels (the type is the schema's name;
    its definition the ``message_definitions`` table's, where the file has
    one), the ``messages`` table the messages by timestamp.
    """

    def __init__(self, path, topics=None, load_messages=True):
        """Read the topics (and the messages) of ``path``."""
        self.path = str(path)
        self.cut, self.summary = '', None
        self.header = Header(profile='ros2', library='rosbag2 sqlite3')
        self.metadata = []
        try:
            self._db = sqlite3.connect(f'file:{self.path}?mode=ro', uri=True)
            rows = self._db.execute('SELECT id, name, type, serialization_format, '
                                    'offered_qos_profiles FROM topics').fetchall()
            defs = {}
            tables = {r[0] for r in self._db.execute(
                "SELECT name FROM sqlite_master WHERE type='table'")}
            if 'message_definitions' in tables:
                defs = {t: (enc, text) for t, enc, text in self._db.execute(
                    'SELECT topic_type, encoding, encoded_message_definition '
                    'FROM message_definitions')}
        except sqlite3.Error as exc:
            raise RecordingError(f'{self.path}: not a readable rosbag2 sqlite3 file '
                                 f'({exc})') from None
        self.schemas, self.channels, sid = {}, {}, {}
        for tid, name, mtype, fmt, qos in rows:
            if mtype not in sid:
                sid[mtype] = len(sid) + 1
                enc, text = defs.get(mtype, ('ros2msg', ''))
                self.schemas[sid[mtype]] = Schema(id=sid[mtype], name=mtype, encoding=enc,
                                                  data=(text or '').encode())
            self.channels[tid] = Channel(id=tid, topic=name, message_encoding=fmt,
                                         metadata={'offered_qos_profiles': qos or ''},
                                         schema_id=sid[mtype])
        self.topic_types = {c.topic: self.schemas[c.schema_id].name
                            for c in self.channels.values()}
        self.messages = []
        if load_messages:
            self.load(topics)

    def load(self, topics=None):
        """Read the messages (of ``topics`` only) by timestamp."""
        topic_of = {cid: c.topic for cid, c in self.channels.items()
                    if not topics or c.topic in set(topics)}
        try:
            rows = self._db.execute('SELECT timestamp, topic_id, data FROM messages '
                                    'ORDER BY timestamp, id').fetchall()
        except sqlite3.Error as exc:
            raise RecordingError(f'{self.path}: unreadable messages table ({exc})') from None
        self.messages = [(int(t), topic_of[c], bytes(d)) for t, c, d in rows if c in topic_of]

    def topic_arrays(self, topics):
        """Return None: the messages are read from the table."""
        return None

    def statistics(self):
        """Return the counts and times of the messages read."""
        return Recording.statistics(self)
