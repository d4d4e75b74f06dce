"""
The command line ``leadscrew_sim``: the parser of all verbs and the one-line error handling.

Every error prints one line ``leadscrew_sim: error: ...`` on stderr and exits
with status 1 (2 for command-line usage errors); set ``LEADSCREW_SIM_DEBUG=1``
for tracebacks.
"""
import os
import sys

from . import (commission, excite, freqresp, identify, info, play, plot, pullout, recover,
               resim, simulate, stability)
from .args import flag_namer, Parser, PROG, UsageError
from ..offline.options import RunError
from ..core.params import ParameterError
from ..core.warmup import kernel_ready
from ..io.mcap_reader import RecordingError
from ..io.run_file import RunFileError

#: The verbs that run the compiled kernel: a first run says that it compiles it.
KERNEL_VERBS = ('simulate', 'resim', 'identify', 'stability', 'freqresp', 'pullout',
                'commission')

#: (verb, module with add_arguments, run and HELP), in the order of ``--help``.
#: ``summary`` is an alias of ``info``.
VERBS = (('simulate', simulate), ('info', info), ('summary', info), ('resim', resim),
         ('play', play), ('plot', plot), ('excite', excite), ('identify', identify),
         ('stability', stability), ('freqresp', freqresp), ('pullout', pullout),
         ('commission', commission), ('recover', recover))


def build_parser():
    """Return the argument parser of all verbs."""
    parser = Parser(prog=PROG, description='Offline tools for the leadscrew_sim lead screw '
                    'axis: simulate, info, resim, play, plot, excite, identify, stability, '
                    'freqresp, pullout, commission, recover.')
    sub = parser.add_subparsers(dest='command', metavar='COMMAND')
    sub.required = True
    for name, verb in VERBS:
        text = 'alias of info' if name == 'summary' else verb.HELP
        p = sub.add_parser(name, help=text, description=text)
        verb.add_arguments(p)
        p.set_defaults(func=verb.run)
    return parser


def main(argv=None):
    """Run the command line with ``argv`` (default ``sys.argv[1:]``); return the exit status."""
    argv = sys.argv[1:] if argv is None else list(argv)
    parser, args = build_parser(), None
    try:
        args = parser.parse_args(argv)
        if args.command in KERNEL_VERBS and not getattr(args, 'quiet', False):
            kernel_ready(lambda text: print(f'{PROG}: {text}', file=sys.stderr), always=False)
        return args.func(args)
    except UsageError as exc:
        print(f'{PROG}: error: {exc} (see {PROG} --help)', file=sys.stderr)
        return 2
    except RunError as exc:
        print(f'{PROG}: error: {exc.naming(flag_namer(parser, args))}', file=sys.stderr)
        return 1
    except (ParameterError, RecordingError, RunFileError) as exc:
        print(f'{PROG}: error: {exc}', file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print(f'{PROG}: error: interrupted', file=sys.stderr)
        return 130
    except Exception as exc:  # noqa: B902 - never a traceback for the user
        if os.environ.get('LEADSCREW_SIM_DEBUG'):
            raise
        msg = ' '.join(str(exc).split())
        print(f'{PROG}: error: {exc.__class__.__name__}: {msg}', file=sys.stderr)
        return 1


if __name__ == '__main__':
    sys.exit(main())
