"""The verbs' shared parser pieces: the one-line parser, its usage error, shared options."""
import argparse
import functools
import sys

from ..offline.foreign.mapping import COMMAND_KINDS, KIND_ALIASES
from ..offline.options import option_text, RunError

PROG = 'leadscrew_sim'


class UsageError(RunError):
    """A command-line usage error (exit status 2)."""


class Parser(argparse.ArgumentParser):
    """ArgumentParser whose errors are one line (no usage dump)."""

    def error(self, message):
        """Raise UsageError instead of printing the usage and exiting."""
        raise UsageError(message)


def add_compression_argument(p):
    """Add ``--compression`` (of the MCAP chunks written) to parser ``p``."""
    p.add_argument('--compression', choices=('lz4', 'zstd', 'none'), default='lz4',
                   help='chunk compression of the MCAP written (default lz4: written and read '
                        'about twice as fast as zstd, files about a third larger)')


def flag_namer(parser, args):
    """
    Return name_of(keyword) -> the flag of the verb ``args.command`` that sets it.

    The run library names options by their keywords (:class:`RunError`); a
    keyword that is an option's destination is named by the option's first
    spelling (``-o``, ``--set``), any other by its flag form (``step_rate``:
    ``--step-rate``).
    """
    flags = {}
    verb = getattr(args, 'command', None)
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction) and verb in action.choices:
            for a in action.choices[verb]._actions:
                if a.option_strings and a.help != argparse.SUPPRESS:
                    flags.setdefault(a.dest, a.option_strings[0])

    def name_of(keyword):
        return flags.get(keyword) or '--' + keyword.replace('_', '-')
    return name_of


@functools.lru_cache(maxsize=None)
def verb_flags(add_arguments):
    """
    Return name_of(keyword) -> the flag of the verb whose options ``add_arguments`` adds.

    Named as :func:`flag_namer` names them, for the texts a verb prints that
    name options as ``<<keyword>>`` (report lines, hints, warnings): its
    ``run(args)`` has no parser, so this builds one of the verb's own options
    (the verb passes its ``add_arguments``; importing the command line's
    parser here would tie the modules in an import circle).
    """
    parser = Parser(prog=PROG)
    add_arguments(parser.add_subparsers(dest='command').add_parser('verb'))
    return flag_namer(parser, argparse.Namespace(command='verb'))


def flag_text(add_arguments, text):
    """Return ``text`` with each ``<<keyword>>`` named as :func:`verb_flags` names it."""
    return option_text(text, verb_flags(add_arguments))


class _DeprecatedAlias(argparse.Action):
    """Store the value like the option it stands for and print one deprecation line."""

    def __init__(self, option_strings, dest, new=None, **kwargs):
        super().__init__(option_strings, dest, **kwargs)
        self.new = new

    def __call__(self, parser, namespace, values, option_string=None):
        """Print the deprecation line on stderr and store ``values`` in ``dest``."""
        print(f'{PROG}: warning: {option_string} is deprecated here; use {self.new}',
              file=sys.stderr)
        setattr(namespace, self.dest, values)


def add_deprecated_alias(p, old, new, dest, type=None):
    """
    Add ``old`` to parser ``p``: a hidden spelling of option ``new`` (same ``dest``).

    It takes one value of ``type``, is not shown in ``--help`` and prints
    ``leadscrew_sim: warning: OLD is deprecated here; use NEW`` on stderr when used.
    """
    p.add_argument(old, dest=dest, type=type, action=_DeprecatedAlias, new=new,
                   default=argparse.SUPPRESS, help=argparse.SUPPRESS)


def add_mapping_arguments(p, step_rate_dest='step_rate'):
    """
    Add the mapping options of a foreign recording to parser ``p``.

    ``step_rate_dest``: the attribute of ``--step-rate`` (``identify`` keeps ``rate``).
    """
    g = p.add_argument_group('mapping of a foreign recording (a real axis\'s bag)')
    g.add_argument('--map', metavar='FILE.yaml', help='the mapping keys below in a YAML file '
                   '(state_topic: ..., command_index: ...); options given here win')
    g.add_argument('--state-topic', help='sensor_msgs/JointState topic of the measured states '
                   '(default joint_states)')
    g.add_argument('--screw-joint', help='joint name of the screw (motor) in the states '
                   '[rad, rad/s, N m]')
    g.add_argument('--nut-joint', help='joint name of the nut in the states [m, m/s, N]')
    g.add_argument('--command-topic', action='append',
                   help='command topic: std_msgs/Float64, std_msgs/Float64MultiArray, '
                   'sensor_msgs/JointState or trajectory_msgs/JointTrajectory; repeat it for '
                   'the topics of several controllers (the latest command acts)')
    g.add_argument('--command-kind', choices=COMMAND_KINDS + tuple(KIND_ALIASES),
                   action='append',
                   help='what a Float64 (or Float64MultiArray entry) command is: motor torque '
                   '[N m], nut velocity [m/s] or nut position [m]; effort (ros2_control\'s '
                   'interface name) is the motor torque; once for all command topics or once '
                   'per topic (default: the kind the topic\'s name says)')
    g.add_argument('--command-index', type=int, metavar='N', action='append',
                   help='entry of a Float64MultiArray command [-] (default 0); once, or once '
                   'per command topic')
    g.add_argument('--command-joint', metavar='NAME', action='append',
                   help='joint of a JointState or JointTrajectory command (default: the nut '
                   'joint where named, else the screw joint); once, or once per topic')
    g.add_argument('--command-delay', type=float, metavar='S',
                   help='constant delay from a command to its effect [s] (default: estimated)')
    g.add_argument('--step-rate', dest=step_rate_dest, type=float, metavar='HZ',
                   help='step rate [Hz] of the re-simulation (default 1000, or the command '
                   'rate where faster)')
    return g
