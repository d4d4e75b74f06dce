"""
Run settings of the node (everything but the physics), on the schema of the physics fields.

The node declares them as ROS parameters, ``simulate`` writes them into its
recordings and ``resim`` reads them back: all through :class:`RunSettings`,
so each value is coerced and checked in one place.
"""
import dataclasses
import re

from .fields import document, field, ParameterError, Schema

#: The clock modes of the node.
CLOCK_MODES = ('realtime', 'stepped', 'lockstep')
#: File name prefix of the recordings: no paths, no surprises in a shell.
PREFIX_RE = re.compile(r'^[A-Za-z0-9_-]{1,64}$')
#: Smallest non-zero file split [B] (a smaller one starts a file every few messages).
MIN_SPLIT_BYTES = 1 << 16
#: Smallest non-zero file split [s].
MIN_SPLIT_SECONDS = 1.0
#: Longest joint_prefix [characters]: the joint names go out in every joint_states.
MAX_JOINT_PREFIX = 128

__all__ = ['CLOCK_MODES', 'MAX_JOINT_PREFIX', 'MIN_SPLIT_BYTES', 'MIN_SPLIT_SECONDS',
           'PREFIX_RE', 'RunSettings']


@document
@dataclasses.dataclass(frozen=True)
class RunSettings(Schema):
    """Rate, clock, command and recording settings of a run (SI units)."""

    update_rate: float = field(1000.0, 'Hz', 'simulation and publication rate', 1.0, 20000.0,
                               read_only=True)
    clock_mode: str = field(
        'realtime', '-', 'realtime: wall-clock paced, stamps from the ROS time at start; '
        'stepped: sim time from 0 with /clock, as fast as possible or paced by '
        'real_time_factor; lockstep: one step per received command, with /clock',
        choices=CLOCK_MODES, read_only=True)
    real_time_factor: float = field(0.0, '-', 'stepped mode pacing: sim seconds per wall '
                                    'second; 0 runs as fast as possible', 0.0, 1000.0)
    joint_prefix: str = field('', '-', 'prefix of the joint names screw_joint and nut_joint')
    joint_command_mode: str = field(
        'auto', '-', 'mode of joint_commands: auto (a finite position commands position, '
        'else a velocity velocity, else an effort torque; the others are feed-forwards) or '
        'the command interface of a ros2_control URDF, fixed (messages without it update the '
        'feed-forwards)', choices=('auto', 'position', 'velocity', 'effort'))
    command_timeout: float = field(
        0.5, 's', 'a command older than this times out like a drive losing communication: '
        'torque goes to 0, a velocity command to a quick stop and hold, a position target '
        'holds (wall clock in realtime mode, sim time otherwise); 0 disables', 0.0, 3600.0)
    max_catchup_steps: int = field(10, '-', 'extra fixed steps a late realtime tick may '
                                   'publish; the older steps of a longer stall are integrated '
                                   'and recorded but not published (skipped_steps)', 0, 1000)
    publish_decimation: int = field(1, '-', 'publish the states every N-th step (/clock: '
                                    'every step)', 1, 100000)
    publish_tf: bool = field(False, '-', 'publish robot_description (transient local), '
                             '/tf_static and /tf from the URDF of the axis (for stacks without '
                             'robot_state_publisher); recordings carry them in any case',
                             read_only=True)
    record: bool = field(True, '-', 'record commands and states to an MCAP file')
    record_dir: str = field('runs', '-', 'directory of the MCAP recordings (start-up only: a '
                            'run-time change could point the writes anywhere)', read_only=True)
    record_prefix: str = field('leadscrew', '-', 'file name prefix of the recordings: 1 to 64 '
                               'letters, digits, _ or -')
    record_split_bytes: int = field(0, 'B', 'start a new file after this many bytes; 0 never, '
                                    f'else at least {MIN_SPLIT_BYTES}', 0, 2 ** 62)
    record_split_seconds: float = field(0.0, 's', 'start a new file after this long; 0 never, '
                                        f'else at least {MIN_SPLIT_SECONDS:g} s', 0.0, 1e9)
    record_flush_interval: float = field(1.0, 's', 'flush the recording at least this often '
                                         '(bounds the loss on a crash)', 0.0, 3600.0)
    record_max_total_bytes: int = field(
        1 << 30, 'B', 'bound of the total size of the recordings of record_prefix in '
        'record_dir: the oldest are deleted before a new file starts (files split at an '
        f'eighth of it unless record_split_bytes is set); 0 none, else at least '
        f'{8 * MIN_SPLIT_BYTES}', 0, 2 ** 62)
    stats_file: str = field('', '-', 'if set, write timing statistics (JSON) to this path at '
                            'shutdown (start-up only)', read_only=True)
    ageing_state_file: str = field('', '-', 'if set, the ageing state (wear, lubricant, screw '
                                   'temperature) is loaded from this file at start and written '
                                   'to it at shutdown and every ageing_state_period (start-up '
                                   'only)', read_only=True)
    ageing_state_period: float = field(60.0, 's', 'how often the ageing state file is written '
                                       '(wall time)', 1.0, 86400.0)

    def _check_consistency(self):
        """Check the rules of the string and split settings beyond their type and range."""
        for name in ('record_prefix', 'record_dir', 'stats_file', 'ageing_state_file',
                     'joint_prefix',
                     'record_split_bytes', 'record_split_seconds', 'record_max_total_bytes'):
            check_rule(name, getattr(self, name))


def check_rule(name, value):
    """Raise ParameterError if a run setting breaks a rule beyond its type and range."""
    shown = repr(value) if len(repr(value)) <= 80 else repr(value)[:77] + '...'
    if name == 'record_prefix' and not PREFIX_RE.match(value):
        raise ParameterError(name, f'{shown} must be 1 to 64 letters, digits, _ or - '
                             '(it starts the file names: no paths)')
    if name in ('record_dir', 'stats_file', 'ageing_state_file', 'joint_prefix') and any(
            ord(c) < 32 or ord(c) == 127 for c in value):
        raise ParameterError(name, f'{shown} contains control characters')
    if name == 'record_dir' and not value:
        raise ParameterError(name, 'must not be empty')
    if name == 'joint_prefix' and (len(value) > MAX_JOINT_PREFIX
                                   or any(c.isspace() for c in value)):
        raise ParameterError(name, f'{shown} must be at most {MAX_JOINT_PREFIX} characters '
                             'without spaces')
    if name == 'record_split_bytes' and 0 < value < MIN_SPLIT_BYTES:
        raise ParameterError(name, f'{value} B would start a new file every few messages: '
                             f'give 0 (never) or at least {MIN_SPLIT_BYTES} B')
    if name == 'record_max_total_bytes' and 0 < value < 8 * MIN_SPLIT_BYTES:
        raise ParameterError(name, f'{value} B leaves no room for a file: give 0 (no bound) '
                             f'or at least {8 * MIN_SPLIT_BYTES} B')
    if name == 'record_split_seconds' and 0.0 < value < MIN_SPLIT_SECONDS:
        raise ParameterError(name, f'{value!r} s would start many files a second: give 0 '
                             f'(never) or at least {MIN_SPLIT_SECONDS:g} s')
