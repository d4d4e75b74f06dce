"""``recover``: write a complete copy of a recording cut short by a crash (the source is kept)."""
from pathlib import Path

from ..io.session import recover
from ..offline.options import NS, RunError

HELP = 'write a complete, indexed copy of a recording cut short by a crash'


def add_arguments(p):
    """Add the options of ``recover`` to parser ``p``."""
    p.add_argument('file', help='the cut MCAP file (read only, never changed)')
    p.add_argument('-o', '--output', metavar='OUT.mcap',
                   help='the repaired copy (default: FILE with .recovered.mcap)')
    p.add_argument('--force', action='store_true', help='overwrite OUT if it exists')
    p.add_argument('-q', '--quiet', action='store_true', help='print nothing but errors')


def run(args):
    """Recover ``args.file`` into the output; print what was saved and lost; return 0."""
    src = Path(args.file)
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
