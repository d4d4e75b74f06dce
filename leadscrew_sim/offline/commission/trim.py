"""A time window of a recording as a new MCAP file: the same schemas, channels and metadata."""
from ..options import NS, RunError
from ...io.mcap_writer import McapWriter


def write_window(rec, dst, t_end, t_start=None):
    """
    Write the messages of ``rec`` logged in [t_start, t_end) [s] and all its metadata to ``dst``.

    ``t_start`` None keeps the recording's start: a re-simulation of the copy
    starts from the recorded initial state.

    Parameters
    ----------
    rec : Recording
        The recording, its messages loaded.
    dst : str
        The new MCAP file.
    t_end, t_start : float
        The window [s] of log time.

    """
    a = -1 if t_start is None else int(round(t_start * NS))
    b = int(round(t_end * NS))
    try:
        with open(dst, 'wb') as fo:
            w = McapWriter(fo, profile=rec.header.profile, library=rec.header.library)
            for name, data in rec.metadata:
                w.add_metadata(name, dict(data))
            schemas = {sid: w.register_schema(s.name, s.encoding, s.data)
                       for sid, s in rec.schemas.items()}
            ids = {c.topic: w.register_channel(c.topic, c.message_encoding,
                                               schemas.get(c.schema_id, 0), dict(c.metadata))
                   for c in rec.channels.values()}
            for t, topic, data in rec.messages:
                if a <= t < b:
                    w.add_message(ids[topic], t, data, t)
            w.finish()
    except OSError as exc:
        raise RunError(f'{dst}: {exc.strerror or exc}') from None
