"""
The ``stability`` verb: when does the axis stick-slip or squeal (doc/stability.md).

Parses the flags (interfaces.md, Analysis v3), calls
:func:`leadscrew_sim.analysis.stability.stability_table` and prints its
summary: the linear boundary along each axis and the worst case.
"""
import math
import sys

from ..analysis.stability import stability_table
from ..offline.options import load_params, parse_sets, RunError

HELP = 'stability of steady sliding: growth rate, mechanism, stick-slip (CSV, PNG map)'


def add_arguments(p):
    """Add the verb's flags to the parser ``p``."""
    p.add_argument('--preset', help='preset name (default: the default preset)')
    p.add_argument('--params', help='ROS 2 parameter file (<node>: ros__parameters:)')
    p.add_argument('--set', action='append', metavar='NAME=VALUE',
                   help='override a physics parameter (repeatable)')
    p.add_argument('--speed', type=float, help='nut speed [m/s], sign = direction along +x '
                   '(unless speed is a grid axis)')
    p.add_argument('--drive', choices=('velocity', 'ideal'), default='velocity',
                   help='the servo velocity loop, or a prescribed motor angle (default velocity)')
    p.add_argument('--grid', action='append', default=[], metavar='NAME=START:STOP:N[:log]',
                   help='a grid axis: speed or a numeric model parameter (at most 3)')
    p.add_argument('--method', choices=('linear', 'nonlinear', 'both'), default='both',
                   help='linear analysis, nonlinear runs or both (default both)')
    p.add_argument('--duration', type=float, default=2.0,
                   help='length of each nonlinear run [s] (default 2)')
    p.add_argument('--workers', type=int, help='local worker processes (default: the cores)')
    p.add_argument('--scheduler', metavar='tcp://HOST:PORT', help='run on a Dask scheduler')
    p.add_argument('--output', '-o', metavar='FILE.csv', help='write the table as CSV')
    p.add_argument('--plot', metavar='FILE.png', help='write the map as PNG')
    p.add_argument('--quiet', '-q', action='store_true', help='no progress bar, no summary')


def _fmt(v):
    return f'{v:.4g}' if isinstance(v, float) else str(v)


def _summary(res, out):
    rows = res['rows']
    n_err = sum(1 for r in rows if r['error'])
    print(f'{len(rows)} case(s), {n_err} with an error'
          + ('' if res['complete'] else ' (INCOMPLETE: interrupted)'), file=out)
    for name, vals in res['boundaries'].items():
        where = ', '.join(_fmt(v) for v in vals[:8]) if vals else 'none in the range'
        more = f' (+{len(vals) - 8} more)' if len(vals) > 8 else ''
        print(f'linear boundary along {name}: {where}{more}', file=out)
    for name, spans in res.get('bistable', {}).items():
        if spans:
            where = ', '.join(f'{_fmt(a)} .. {_fmt(b)}' for a, b in spans[:8])
            more = f' (+{len(spans) - 8} more)' if len(spans) > 8 else ''
            print(f'bistable along {name} (the small start decays, the large one keeps '
                  f'oscillating): {where}{more}', file=out)
    w = res['worst']
    if w is None:
        print('worst case: none (every case failed)', file=out)
        return
    keys = res['names'] + ['growth_rate', 'frequency', 'mechanism', 'verdict',
                           'amplitude_large', 'stick_fraction', 'period']
    text = ', '.join(f'{k}={_fmt(w[k])}' for k in keys
                     if not (isinstance(w[k], float) and math.isnan(w[k])) and w[k] != '')
    print(f'worst case: {text}', file=out)
    if len(rows) == 1 and w['error']:
        print(f'error: {w["error"]}', file=out)


def run(args):
    """Run the verb; return the exit status (1 if the run was interrupted)."""
    phys, _ = parse_sets(args.set)
    params, _, _ = load_params(args, phys)
    if args.workers is not None and args.workers < 1:
        raise RunError(f'--workers {args.workers}: must be at least 1')
    res = stability_table(params, args.grid, speed=args.speed, drive=args.drive,
                          method=args.method, duration=args.duration, workers=args.workers,
                          scheduler=args.scheduler, csv_path=args.output,
                          plot_path=args.plot, progress=not args.quiet)
    if not args.quiet:
        _summary(res, sys.stdout)
    if len(res['rows']) == 1 and res['rows'][0]['error']:
        raise RunError(res['rows'][0]['error'])
    return 0 if res['complete'] else 1
