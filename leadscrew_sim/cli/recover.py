"""
``recover``: write a complete copy of a recording cut short by a crash (the source is kept).

A rosbag2 bag directory becomes one complete MCAP file: its split files
merged in log-time order, a cut last file up to its last whole chunk. The run
is :func:`leadscrew_sim.offline.recover.recover_recording`; this verb prints it.
"""
from pathlib import Path

from ..offline.options import NS
from ..offline.recover import recover_recording

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
    done = recover_recording(args.file, args.output, args.force)
    if not args.quiet:
        for line in summary_lines(done, args.file):
            print(line)
    return 0


def summary_lines(done, src):
    """Return the lines that say what a recovery (a Recovered) saved and what it lost."""
    n = sum(done.topics.values())
    span = ''
    if done.log_times:
        a, b = done.log_times
        span = f', log time {a / NS:.3f} .. {b / NS:.3f} s ({(b - a) / NS:.3f} s)'
    if done.files > 1 or Path(src).is_dir():
        return [f'wrote {done.path}: {n} messages on {len(done.topics)} topics from '
                f'{done.files} file(s) of {src}{span}',
                f'{src}: ' + (done.problem if not done.whole else 'every file whole')]
    lines = [f'wrote {done.path}: {n} messages on {len(done.topics)} topics{span}']
    lines += [f'  {c:9d}  {t}' for t, c in sorted(done.topics.items())]
    if done.whole:
        lines.append(f'{src} ends whole: every message of its data section is in the copy')
    else:
        lines.append(f'{src} stops being whole at byte {done.end} of {done.size}: '
                     f'{done.problem}; lost: the last {done.lost_bytes} B (an unfinished '
                     'chunk: the messages since the last flush)')
    return lines
