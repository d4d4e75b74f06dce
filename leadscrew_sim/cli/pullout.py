"""
The ``pullout`` verb: a stepper axis's pull-out torque against step rate (doc/model.md).

Parses the flags, calls :func:`leadscrew_sim.offline.pullout.pullout_curve`
and prints the table; ``-o`` writes it as CSV, ``--plot`` as a PNG.
"""
from ..core.presets import preset_label
from ..offline.options import load_params, parse_sets, RunError
from ..offline.pullout import plot_png, pullout_curve, write_csv

HELP = "pull-out torque of a stepper axis's motor and driver against step rate (CSV, PNG)"


def add_arguments(p):
    """Add the verb's flags to the parser ``p``."""
    p.add_argument('--preset', help='preset name or YAML path of a stepper axis '
                   '(e.g. nema17_tr8x8)')
    p.add_argument('--params', help='ROS 2 parameter file (<node>: ros__parameters:)')
    p.add_argument('--set', action='append', metavar='NAME=VALUE',
                   help='override a physics parameter (repeatable)')
    p.add_argument('--rates', metavar='R1,R2,...', help='step rates [full steps/s] (default: '
                   '0.1, 0.2, ... 1 of max_step_rate)')
    p.add_argument('--ramp', type=float, default=2.0,
                   help='time of each load ramp to 1.2 holding torque [s] (default 2)')
    p.add_argument('--output', '-o', metavar='FILE.csv', help='write the table as CSV')
    p.add_argument('--plot', metavar='FILE.png', help='write the curve as PNG')
    p.add_argument('--quiet', '-q', action='store_true', help='print nothing')


def run(args):
    """Measure, print and write the pull-out table; return 0."""
    phys_ov, _run_ov = parse_sets(args.set)
    params, label, _extra = load_params(args, phys_ov)
    rates = None
    if args.rates:
        try:
            rates = [float(x) for x in args.rates.split(',')]
        except ValueError:
            raise RunError(f'--rates {args.rates!r}: give numbers separated by commas') from None
    if not args.ramp > 0.0:
        raise RunError(f'--ramp {args.ramp} s must be > 0')
    rows = pullout_curve(params, rates, args.ramp)
    if args.output:
        write_csv(rows, args.output)
    if args.plot:
        plot_png(rows, params, preset_label(label), args.plot)
    if not args.quiet:
        print(f'{"step rate [full steps/s]":>24} {"speed [rev/s]":>13} {"pull-out [N m]":>15}')
        for r in rows:
            print(f'{r["step_rate"]:24.0f} {r["speed"]:13.2f} {r["pullout_torque"]:15.4f}')
    return 0
