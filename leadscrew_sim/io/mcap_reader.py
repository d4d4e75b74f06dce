"""
Reading a whole MCAP file: header, channels, metadata and messages, with one-line errors.

Any ros2-profile file is read; :meth:`Recording.require_ours` tells a
leadscrew_sim run file (:mod:`.run_file`) from others.
"""
from mcap.reader import make_reader

from .mcap_writer import MAGIC
from .run_file import PARAMS_RECORD
from .topics import TOPICS

__all__ = ['Recording', 'RecordingError']


class RecordingError(ValueError):
    """A file that is missing, not MCAP, truncated, corrupt or of the wrong kind."""


class Recording:
    """
    A fully read MCAP file: header, channels, metadata and the messages in log-time order.

    ``messages`` holds ``(log_time [ns], topic, data)``; messages of one log
    time keep their file order.

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
        """Read ``path``; raise RecordingError for missing, truncated or corrupt files."""
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
            try:
                self._read(fh, topics, load_messages)
            except Exception as exc:  # noqa: B902 - mcap raises many kinds on bad data
                detail = str(exc).splitlines()[0] if str(exc) else exc.__class__.__name__
                raise RecordingError(f'{self.path}: truncated or corrupt MCAP file ({detail}); '
                                     'a truncated recording can be repaired with '
                                     'leadscrew_sim.io.session.recover()') from None
        self.profile = self.header.profile
        self.topic_types = {c.topic: self.schemas[c.schema_id].name if c.schema_id in
                            self.schemas else '' for c in self.channels.values()}

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
            for _schema, channel, msg in reader.iter_messages(topics=topics,
                                                              log_time_order=False):
                if want is None or channel.topic in want:
                    msgs.append((msg.log_time, channel.topic, msg.data))
            msgs.sort(key=lambda m: m[0])        # stable: ties keep file order

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
        longer = [k for k in TOPICS if k != rel and k.endswith('/' + rel)]
        for topic in self.topic_types:
            if (topic == rel or topic.endswith('/' + rel)) and not any(
                    topic == '/' + k or topic.endswith('/' + k) for k in longer):
                return topic
        return None
