"""
``identify``: fit parameters so that re-simulating a recording's commands gives its states.

The fit is :func:`leadscrew_sim.offline.identify.run.fit_recording`; this verb
parses its options, prints the report (:mod:`.identify_report`) and has the
report, the parameter file and the plot written.
"""
from .args import add_deprecated_alias, add_mapping_arguments, verb_flags
from .identify_report import report
from ..analysis.identify import fit as ident
from ..offline.identify.run import fit_recording
from ..offline.identify.output import write_outputs
from ..offline.identify.progress import FitProgress
from ..offline.options import keep_freed_memory

HELP = 'fit friction, backlash and other parameters to a recording'


def add_arguments(p):
    """Add the options of ``identify`` to parser ``p``."""
    p.add_argument('file', help='the recording (MCAP file or rosbag2 bag directory)')
    p.add_argument('--fit', help=f'comma list of parameters to fit (default '
                   f'{",".join(ident.DEFAULT_FIT)}; fittable: {", ".join(ident.FITTABLE)})')
    p.add_argument('--preset', help='starting and fixed values: a preset (default: the one '
                   'the recording names, else tr12x3)')
    p.add_argument('--params', help='starting and fixed values: a ROS 2 parameter file')
    p.add_argument('--set', action='append', metavar='NAME=VALUE',
                   help='a starting or fixed value (repeatable; YAML scalar in the '
                   'parameter\'s unit)')
    p.add_argument('-o', '--output-params', metavar='FILE.yaml', help='write the fitted set '
                   'as a parameter file (simulate --params, the node)')
    p.add_argument('--report', metavar='FILE', help='also write the report (it is printed)')
    p.add_argument('--plot', metavar='FILE.png', help='recorded, initial and fitted signals')
    add_mapping_arguments(p, step_rate_dest='rate')
    add_deprecated_alias(p, '--rate', '--step-rate', 'rate', float)
    p.add_argument('--max-nfev', type=int, metavar='N',
                   help='most re-simulations per fit stage [-]')
    p.add_argument('--restarts', choices=('auto', 'on', 'off'), default='auto',
                   help='restart the re-simulation from the recorded state at each rest of '
                   'a torque-mode recording and compare only the steps that state '
                   'determines (auto: when one run from the start does not explain the '
                   'recording; on: always; off: never)')
    p.add_argument('--write-all', action='store_true', help='with --output-params: write '
                   'every parameter (the unidentified ones at their starting values, marked '
                   'by a comment), not only the identified ones')
    p.add_argument('--quiet', '-q', action='store_true', help='print neither the report nor '
                   'the progress (shown on a terminal only)')


def run(args):
    """Fit the parameters and write the report, the parameter file and the plot."""
    keep_freed_memory()                 # thousands of re-simulations reuse their blocks
    progress = None if args.quiet else FitProgress()      # on a terminal only
    try:
        out = fit_recording(args, progress)
    finally:
        if progress is not None:
            progress.done()
    flags = verb_flags(add_arguments)
    text = report(args.file, out, flags)
    if not args.quiet:
        print(text)
    write_outputs(args, out, text, flags)
    return 0
