"""
The ``recover`` run: a complete copy of a recording cut short by a crash (the source is kept).

An MCAP file is copied up to its last whole record
(:func:`leadscrew_sim.io.session.recover`); a rosbag2 bag directory becomes
one complete MCAP file, its split files merged in log-time order, a cut last
file up to its last whole chunk (:func:`leadscrew_sim.io.session.recover_bag`).
"""
import dataclasses
from pathlib import Path

from .options import open_recording, RunError
from ..io.session import recover, recover_bag


@dataclasses.dataclass(frozen=True)
class Recovered:
    """
    What a recovery saved and lost.

    ``path``: the copy written; ``topics``: topic -> messages saved;
    ``log_times``: (first, last) log time [ns] of the saved messages, or None;
    ``whole``: the source was whole; ``problem``: why and ``end`` (byte) where
    it stops being whole; ``lost_bytes``: the bytes after that; ``files``: the
    bag's files read (1 for an MCAP file).
    """

    path: str
    topics: dict
    log_times: object
    whole: bool
    problem: str
    end: int
    size: int
    lost_bytes: int
    files: int


def recover_recording(source, output=None, force=False):
    """
    Write a complete copy of the recording ``source``; return :class:`Recovered`.

    Parameters
    ----------
    source : str or Path
        A cut MCAP file or a rosbag2 bag directory (read only, never changed).
    output : str or Path, optional
        The copy (default the source with ``.recovered.mcap``).
    force : bool
        Overwrite the copy if it exists.

    Raises
    ------
    RunError
        A missing source, a copy that would replace it or exists, an unreadable file.

    """
    src = Path(source)
    if src.is_dir():
        return _bag(src, output, force)
    if not src.is_file():
        raise RunError(f'{src}: no such file')
    dst = Path(output) if output else src.with_name(src.stem + '.recovered.mcap')
    if dst.resolve() == src.resolve():
        raise RunError(f'output {dst}: the copy must not replace the source')
    if dst.exists() and not force:
        raise RunError(f'{dst} exists (overwrite it with force, or give another output)')
    try:
        found = recover(src, dst)
    except ValueError as exc:
        raise RunError(f'{src}: {exc}') from None
    except OSError as exc:
        raise RunError(f'{exc.filename or dst}: {exc.strerror or exc}') from None
    topics = {}
    for m in found.messages:
        topic = found.channels[m[1]].topic
        topics[topic] = topics.get(topic, 0) + 1
    times = [m[0] for m in found.messages]
    return Recovered(str(dst), topics, (min(times), max(times)) if times else None,
                     bool(found.complete), '' if found.complete else str(found.problem),
                     int(found.end), int(found.size),
                     0 if found.complete else int(found.lost_bytes), 1)


def _bag(src, output, force):
    """Write the bag ``src`` as one complete MCAP file."""
    dst = Path(output) if output else src.with_name(src.name + '.recovered.mcap')
    if dst.exists() and not force:
        raise RunError(f'{dst} exists (overwrite it with force, or give another output)')
    if dst.resolve().parent == src.resolve() or dst.is_dir():
        raise RunError(f'output {dst}: the copy must lie outside the bag and not be a '
                       'directory')
    bag = open_recording(src)
    try:
        recover_bag(bag, dst)
    except OSError as exc:
        raise RunError(f'{exc.filename or dst}: {exc.strerror or exc}') from None
    topics = {}
    for m in bag.messages:
        topics[m[1]] = topics.get(m[1], 0) + 1
    times = [m[0] for m in bag.messages]
    return Recovered(str(dst), topics, (min(times), max(times)) if times else None,
                     not bag.cut, bag.cut or '', 0, 0, 0, len(bag.files))
