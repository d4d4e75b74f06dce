"""
``recover``: write a complete copy of a recording cut short by a crash (the source is kept).

A rosbag2 bag directory becomes one complete MCAP file: its split files
merged in log-time order, a cut last file up to its last whole chunk.
"""
from pathlib import Path

from ..io.session import recover, recover_bag
from ..offline.options import NS, open_recording, RunError

HELP = 'write a complete, indexed copy of a recording cut short by a crash'


def add_arguments(p):
    """Add the options of ``recover`` to parser ``p``."""
    p.add_argument('file', help='the cut MCAP file, or a rosbag2 bag directory (read only, '
                   'never changed)')
    p.add_argument('-o', '--output', metavar='OUT.mcap',
                   help='the repaired copy (default: FILE with .recovered.mcap)')
    p.add_argument('--force', action='store_true', help='overwrite OUT if it exists')
    p.add_argument('-q', '--quiet', action='store_true', help='print nothing but errors')


def run(args):
    """Recover ``args.file`` into the output; print what was saved and lost; return 0."""
    src = Path(args.file)
    if src.is_dir():
        return _bag(args, src)
    if not src.is_file():
        raise RunError(f'{src}: no such file')
    dst = Path(args.output) if args.output else src.with_name(src.stem + '.recovered.mcap')
    if dst.resolve() == src.resolve():
        raise RunError(f'-o {dst}: the copy must not replace the source')
    if dst.exists() and not args.force:
        raise RunError(f'{dst} exists (give --force to overwrite it, or another -o)')
    try:
        found = recover(src, dst)
    except ValueError as exc:
        raise RunError(f'{src}: {exc}') from None
    except OSError as exc:
        raise RunError(f'{exc.filename or dst}: {exc.strerror or exc}') from None
    if not args.quiet:
        for line in summary_lines(found, src, dst):
            print(line)
    return 0


def _bag(args, src):
    """Write the bag ``src`` as one complete MCAP file; print what it holds."""
    dst = Path(args.output) if args.output else src.with_name(src.name + '.recovered.mcap')
    if dst.exists() and not args.force:
        raise RunError(f'{dst} exists (give --force to overwrite it, or another -o)')
    if dst.resolve().parent == src.resolve() or dst.is_dir():
        raise RunError(f'-o {dst}: the copy must lie outside the bag and not be a directory')
    bag = open_recording(src)
    try:
        n = recover_bag(bag, dst)
    except OSError as exc:
        raise RunError(f'{exc.filename or dst}: {exc.strerror or exc}') from None
    if not args.quiet:
        times = [m[0] for m in bag.messages]
        print(f'wrote {dst}: {n} messages on {len(bag.channels)} topics from '
              f'{len(bag.files)} file(s) of {src}' +
              (f', log time {min(times) / NS:.3f} .. {max(times) / NS:.3f} s' if times else ''))
        print(f'{src}: ' + (bag.cut if bag.cut else 'every file whole'))
    return 0


def summary_lines(found, src, dst):
    """Return the lines that say what a recovery saved and what it lost."""
    topics = {}
    for m in found.messages:
        topic = found.channels[m[1]].topic
        topics[topic] = topics.get(topic, 0) + 1
    times = [m[0] for m in found.messages]
    lines = [f'wrote {dst}: {len(found.messages)} messages on {len(topics)} topics'
             + (f', log time {min(times) / NS:.3f} .. {max(times) / NS:.3f} s '
                f'({(max(times) - min(times)) / NS:.3f} s)' if times else '')]
    lines += [f'  {n:9d}  {t}' for t, n in sorted(topics.items())]
    if found.complete:
        lines.append(f'{src} ends whole: every message of its data section is in the copy')
    else:
        lines.append(f'{src} stops being whole at byte {found.end} of {found.size}: '
                     f'{found.problem}; lost: the last {found.lost_bytes} B (an unfinished '
                     'chunk: the messages since the last flush)')
    return lines
