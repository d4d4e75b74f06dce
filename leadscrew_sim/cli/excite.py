"""
``excite``: publish a standard identification profile as commands on the ROS graph.

``leadscrew_sim excite NAME`` publishes the profile's commands on the node's
command topic (or a real axis' driver listening on the same topics) at
``--command-rate`` Hz; record them with the node's recorder or ``ros2 bag record``.
``--list`` and ``--dry-run`` need no ROS. The profile's defaults come from the
axis parameters (``--preset``, ``--params``, ``--set``, as ``simulate``), its
options from ``--opt NAME=VALUE``. The publishing node lives in
:mod:`leadscrew_sim.ros.exciter`; like ``play``, this verb imports rclpy
only when it publishes.
"""
import csv
import importlib
import math

from .args import add_deprecated_alias
from ..offline.options import (check_finite, DEFAULT_PRESET, load_params, parse_options,
                               parse_sets, RunError)
from ..analysis.excitation.profiles import ALL_PROFILES as PROFILES, make_profile

HELP = ('publish an identification profile as commands (breakaway, sweep, reversals, iso230, '
        'chirp, multisine, commission)')


def add_arguments(p):
    """Add the options of ``excite`` to parser ``p``."""
    p.add_argument('name', nargs='?', metavar='NAME',
                   help=f'profile: {", ".join(PROFILES)}')
    p.add_argument('--opt', action='append', metavar='NAME=VALUE',
                   help='a profile option in SI units (repeatable; see --list)')
    p.add_argument('--preset', help=f'axis preset for the defaults (default {DEFAULT_PRESET})')
    p.add_argument('--params', help='ROS 2 parameter file of the axis')
    p.add_argument('--set', action='append', metavar='NAME=VALUE',
                   help='override an axis parameter (repeatable; YAML scalar in the '
                   'parameter\'s unit)')
    p.add_argument('--command-rate', dest='rate', type=float, metavar='HZ',
                   help='commands per second [Hz] (default 100; chirp, multisine: 10 fmax '
                   'within [100, 1000] Hz)')
    add_deprecated_alias(p, '--rate', '--command-rate', 'rate', float)
    p.add_argument('--namespace', default='', help='namespace of the axis\' topics')
    p.add_argument('--joint-commands', action='store_true',
                   help='publish sensor_msgs/JointState on joint_commands instead of Float64')
    p.add_argument('--prefix', default='', help='joint name prefix (with --joint-commands)')
    p.add_argument('--wait-timeout', type=float, default=10.0, metavar='S',
                   help='longest wait for a subscriber [s] (default 10)')
    p.add_argument('--list', action='store_true',
                   help='print the profiles with their options and durations')
    p.add_argument('--dry-run', nargs='?', type=int, const=20, metavar='N',
                   help='print the first N commands (default 20) and exit')
    p.add_argument('-o', '--output', '--log', dest='log', metavar='FILE.csv',
                   help='write every command sent as index,time,value [-, s, SI]')
    p.add_argument('--segments', metavar='FILE.json',
                   help='commission: write the segments sidecar (part names and times from '
                   'the first command) for a recording without the segments record')
    p.add_argument('-q', '--quiet', action='store_true',
                   help='print no progress while publishing (warnings and errors only)')


def run(args):
    """List, dry-run or publish a profile; return the exit status."""
    phys, _run = parse_sets(args.set)
    params, label, _extra = load_params(args, phys)
    options = parse_options(args.opt)
    if args.list:
        names = [args.name] if args.name else list(PROFILES)
        for name in names:
            profile = make_profile(name, params, **(options if args.name else {}))
            print('\n'.join(profile.listing()))
        print(f'(defaults for the axis {label})')
        return 0
    if not args.name:
        raise RunError(f'give a profile NAME ({", ".join(PROFILES)}) or --list')
    profile = make_profile(args.name, params, **options)
    if args.rate is None:
        args.rate = getattr(profile, 'command_rate', 100.0)
    check_finite('command_rate', args.rate)
    if args.rate < getattr(profile, 'min_command_rate', 0.0):
        raise RunError(f'--command-rate {args.rate:g} Hz is below 2.5 fmax = '
                       f'{profile.min_command_rate:g} Hz of the {profile.name}: raise it or '
                       'lower --opt fmax')
    if not 0.1 <= args.rate <= 10000.0:
        raise RunError(f'--command-rate {args.rate:g} Hz must lie in [0.1, 10000] Hz')
    if not (math.isfinite(args.wait_timeout) and args.wait_timeout >= 0.0):
        raise RunError(f'--wait-timeout {args.wait_timeout!r} s must be >= 0')
    if args.segments and profile.kind != 'mixed':
        raise RunError(f'--segments: the {profile.name} profile has no parts (use commission)')
    if args.prefix and not args.joint_commands:
        raise RunError('--prefix names joints: it needs --joint-commands')
    if args.dry_run is not None:
        return _dry_run(profile, args)
    return _publish(profile, args)


def _dry_run(profile, args):
    """Print the first commands the profile would send; return 0."""
    n_total = int(math.ceil(profile.duration * args.rate - 1e-9)) + 1
    topic = 'joint_commands' if args.joint_commands else ', '.join(
        getattr(profile, 'topics', None) or [profile.topic])
    print(f'{profile.describe()}')
    print(f'{n_total} commands on {topic} [{profile.unit}] over {profile.duration:.3f} s at '
          f'{args.rate:g} Hz; the first {min(args.dry_run, n_total)}:')
    for k in range(min(args.dry_run, n_total)):
        t = k / args.rate
        print(f'{t:10.4f} s  {profile(t):+.9g}')
    return 0


def _publish(profile, args):
    """Publish the profile through the exciter node; return its exit code."""
    exciter_mod = importlib.import_module('leadscrew_sim.ros.exciter')
    log_file = writer = None
    if args.log:
        try:
            log_file = open(args.log, 'w', newline='')
        except OSError as exc:
            raise RunError(f'--output {args.log}: {exc.strerror or exc}') from None
        writer = csv.writer(log_file)
        writer.writerow(['index', 'time', 'value'])
    try:
        ex = exciter_mod.Exciter(
            profile, args.rate, namespace=args.namespace, joint_commands=args.joint_commands,
            prefix=args.prefix, out=lambda line: _out(args, line),
            log=None if writer is None else (lambda k, t, v: writer.writerow([k, repr(t),
                                                                             repr(v)])))
        try:
            code = ex.run(args.wait_timeout)
        except exciter_mod.ExciteError as exc:
            raise RunError(str(exc)) from None
        if args.segments and ex.start_ns is not None:
            from ..offline.commission.segments import write_sidecar
            write_sidecar(args.segments, profile, ex.start_ns)
        return code
    finally:
        if log_file is not None:
            log_file.close()


def _out(args, line):
    """Print a progress line of the exciter; with ``--quiet`` only its warnings."""
    if not args.quiet or 'warning' in line:
        print(line, flush=True)
