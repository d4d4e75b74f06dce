"""
``commission``: one recording of ``excite commission``, the axis's report.

``leadscrew_sim commission RUN -o DIR`` writes DIR/fit.yaml (the identified
values as a parameter file), DIR/report.json (every figure) and
DIR/report.html (one self-contained page). RUN is a leadscrew_sim recording,
or a real axis's bag (a rosbag2 directory or ros2 MCAP file) mapped by the
options of ``identify`` (``--command-topic``, the joints, ``--map``) with
its parts in a segments sidecar. The run library is
:mod:`leadscrew_sim.offline.commission.run`; the fit takes the options of
``identify`` (starting values) that this verb passes on.
"""
from .args import add_mapping_arguments, verb_flags
from ..offline.foreign.mapping import Mapping
from ..offline.commission.run import commission
from ..offline.library import identify_options
from ..offline.options import keep_freed_memory

HELP = 'commission an axis from one recording: fit.yaml, report.json and report.html'


def add_arguments(p):
    """Add the options of ``commission`` to parser ``p``."""
    p.add_argument('run', metavar='RUN', help='the recording of `excite commission`: a '
                   'leadscrew_sim MCAP file, or a real axis\'s rosbag2 bag with the mapping '
                   'options')
    p.add_argument('-o', '--output', required=True, metavar='DIR',
                   help='directory of fit.yaml, report.json and report.html (created)')
    p.add_argument('--segments', metavar='FILE.json',
                   help='segments sidecar of a recording without the segments record '
                   '(default RUN.segments.json when it exists)')
    p.add_argument('--preset', help='starting and fixed values: a preset (default: the one '
                   'the recording names, else tr12x3)')
    p.add_argument('--params', help='starting and fixed values: a ROS 2 parameter file')
    p.add_argument('--set', action='append', metavar='NAME=VALUE',
                   help='a starting or fixed value (repeatable; YAML scalar in the '
                   'parameter\'s unit)')
    p.add_argument('-q', '--quiet', action='store_true', help='no progress lines on stderr')
    add_mapping_arguments(p)


def run(args):
    """Commission the recording and write the three files; return 0."""
    keep_freed_memory()
    mapping = Mapping(**{k: getattr(args, 'rate' if k == 'step_rate' and not hasattr(args, k)
                                    else k, None) for k in Mapping.keys()})
    fit_options = identify_options(args.run, preset=args.preset, params=args.params,
                                   set_items=args.set, mapping=mapping, map_file=args.map)
    commission(args.run, args.output, fit_options, args.segments,
               progress=(lambda line: None) if args.quiet else _say,
               name_of=verb_flags(add_arguments))
    return 0


def _say(line):
    import sys
    print(line, file=sys.stderr, flush=True)
