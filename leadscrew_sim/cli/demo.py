"""
``python -m leadscrew_sim.cli.demo``: the node driven by torque pulses (``make run``).

Parses the flags and calls :func:`leadscrew_sim.ros.demo.run`.
"""
import argparse
import sys


def main(argv=None):
    """Parse the demo's flags, run it; return the exit code."""
    from ..ros.demo import __doc__ as doc, run
    from ..ros.parameters import DEFAULT_PRESET
    ap = argparse.ArgumentParser(prog='leadscrew_sim demo',
                                 description=doc.strip().split('\n\n')[0])
    ap.add_argument('--preset', default=DEFAULT_PRESET,
                    help='preset name (config/<name>.yaml); "default" = ' + DEFAULT_PRESET)
    ap.add_argument('--duration', type=float, default=0.0,
                    help='seconds to run [s]; 0 = until Ctrl-C')
    args = ap.parse_args(argv)
    return run(args.preset, args.duration)


if __name__ == '__main__':
    sys.exit(main())
