"""
``resim``: re-run the commands of a recording through the model and compare the states.

The run is :func:`leadscrew_sim.offline.replay.run.resim` (the re-simulation
:class:`leadscrew_sim.offline.replay.resim.Resim`, the comparison
:mod:`leadscrew_sim.offline.replay.compare`); this verb parses its options and
prints the difference table, or the twin's report for a foreign recording.
"""
from .args import add_compression_argument, add_mapping_arguments, verb_flags
from .event_lines import print_events
from ..offline.foreign.twin import plot_twin, report_lines
from ..offline.replay.compare import compare
from ..offline.replay.run import resim, TwinRun

__all__ = ['add_arguments', 'compare', 'HELP', 'run']

HELP = 're-simulate a recording and compare'


def add_arguments(p):
    """Add the options of ``resim`` to parser ``p``."""
    p.add_argument('file', help='the recording (MCAP file or rosbag2 bag directory)')
    p.add_argument('--set', action='append', metavar='NAME=VALUE',
                   help='override a recorded physics parameter (repeatable; YAML scalar in '
                   'the parameter\'s unit)')
    p.add_argument('--output', '-o', metavar='FILE.mcap',
                   help='output MCAP (default <stem>.resim.mcap; a leadscrew_sim recording)')
    add_compression_argument(p)
    p.add_argument('--quiet', '-q', action='store_true', help='no progress bar')
    g = add_mapping_arguments(p)
    g.add_argument('--preset', help='the twin\'s parameters: a preset (a foreign recording)')
    g.add_argument('--params', help='the twin\'s parameters: a ROS 2 parameter file (a '
                   'foreign recording)')
    g.add_argument('--plot', metavar='FILE.png', help='measured vs twin over time (a foreign '
                   'recording)')


def run(args):
    """Re-simulate a recording and print the difference from the recorded states."""
    done = resim(args)
    if isinstance(done, TwinRun):
        return _twin_report(args, done)
    _report(args, done)
    print_events(done.events)
    return 0


def _twin_report(args, done):
    """Print the report of a foreign recording against its twin; plot it with ``--plot``."""
    overrides = f' ({" ".join(args.set)})' if args.set else ''
    for line in report_lines(done.comparison, f' with {done.label}{overrides}',
                             verb_flags(add_arguments)):
        print(line)
    if args.plot:
        plot_twin(done.comparison, args.plot)
        print(f'wrote {args.plot}')
    return 0


def _report(args, done):
    """Print the summary and the difference table of a resim run (a ResimRun)."""
    sim = done.sim
    print(f'resim of {args.file}: {sim.n_steps} steps at dt {sim.dt_ns} ns '
          f'(clock_mode {sim.clock_mode or "?"}), overrides: '
          f'{" ".join(args.set or []) or "none"}; wrote {done.path}')
    if sim.missing:
        print(f'warning: parameters missing from the recording (defaults used): '
              f'{", ".join(sim.missing)}')
    if sim.clock_mode == 'realtime':
        print('note: realtime recording: command timeouts were wall-clock based and '
              'overrun skips are not reproduced')
    print(f'{"topic":<24} {"field":<24} {"max |diff|":>14} {"rms diff":>14} {"n":>8}')
    overall = 0.0
    for topic, field, mx, rms, n in done.rows:
        print(f'{topic:<24} {field:<24} {float(mx)!r:>14} {float(rms)!r:>14} {n:>8}')
        if n:
            overall = max(overall, float(mx))
    compared, bits = done.ticks, done.bit_differences
    note = ''
    if compared and overall == 0.0:
        note = (' (bit-identical)' if not bits else
                f' (equal values, but {bits} differ in their bits: -0.0/+0.0)')
    print(f'compared {compared} recorded ticks; overall max |diff|: {overall!r}{note}')
