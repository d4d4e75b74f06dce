"""
The node's command intake: raw subscription bytes into a CommandHold, with counters and warnings.

The rules (validation, zero-order hold, timeout) are those of
:class:`leadscrew_sim.core.commands.CommandHold`, shared with ``resim``; this
module decodes the messages, counts accepted, rejected and ignored commands
and logs (throttled) what the node refuses or replaces.
"""
import time

from rclpy.serialization import deserialize_message
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64

from ..core.commands import ACCEPTED, CommandHold, DROPPED, IGNORED, JOINT_COMMAND_MODES
from ..core.drive_modes import MODE_NAMES, MODE_TORQUE
from ..io.cdr import decode_float64, DecodeError

NS = 1_000_000_000

__all__ = ['CommandInputs', 'float64_value']


def float64_value(data):
    """
    Return the value of a serialized std_msgs/Float64 (raw subscription bytes).

    Decodes the CDR directly (about 1 us instead of 10 us for
    deserialize_message), falling back to rclpy for any other encapsulation.
    """
    try:
        return decode_float64(data)
    except DecodeError:
        return deserialize_message(data, Float64).data


class CommandInputs:
    """
    The commands of the node: the hold, the counters and the log messages about them.

    Times are integer nanoseconds in the node's time base of command ages
    (wall clock in realtime mode, sim time otherwise); ``cmd_wall`` is the
    monotonic time of the last accepted drive command (None: none yet).

    Parameters
    ----------
    logger : logging-like
        Has ``info`` and ``warn`` (with ``throttle_duration_sec``).
    joint_prefix : str
        Prefix of the joint names.
    timeout : float
        The parameter command_timeout [s].
    nut_map : leadscrew_sim.core.commands.NutMap
        How nut commands map to the motor.
    joint_command_mode : str
        The run setting joint_command_mode.
    params : ScrewParams, optional
        The command delay and drop rate (:meth:`CommandHold.set_faults`).

    """

    def __init__(self, logger, joint_prefix, timeout, nut_map=None, joint_command_mode='auto',
                 params=None):
        """Start with no command."""
        self.hold = CommandHold(joint_prefix, timeout, nut_map, joint_command_mode, params)
        self._log = logger
        self.cmd_wall = None
        self.rejected = 0                  # malformed or non-finite commands
        self.ignored = 0                   # joint_commands without our joints
        self.commands = 0
        self._warned_no_joint = False

    def set_joint_prefix(self, joint_prefix):
        """Follow a run-time change of joint_prefix."""
        self.hold.set_joint_prefix(joint_prefix)

    def set_joint_command_mode(self, mode):
        """Follow a run-time change of joint_command_mode."""
        self.hold.joint_mode = JOINT_COMMAND_MODES[mode]

    def set_timeout(self, timeout):
        """Follow a run-time change of command_timeout [s]."""
        self.hold.timeout = float(timeout)

    def reset(self, nut_map=None):
        """
        Forget every command (``~/reset``); the counters stay.

        Parameters
        ----------
        nut_map : leadscrew_sim.core.commands.NutMap, optional
            The nut-to-motor map of the state reset to (as after homing again).

        """
        self.hold.reset()
        if nut_map is not None:
            self.hold.nut_map = nut_map
        self.cmd_wall = None

    def _reject(self, what):
        self.rejected += 1
        self._log.warn(f'rejected {what} ({self.rejected} so far)', throttle_duration_sec=1.0)

    def _accepted(self, was_stale):
        """Count an accepted drive command; ``was_stale``: the hold was stale before it."""
        self.cmd_wall = time.monotonic_ns()
        self.commands += 1
        if was_stale:
            self._log.info(f'{MODE_NAMES[self.hold.mode]} command resumed')

    def _take(self, reason, was_stale):
        if reason is DROPPED:
            return
        if reason:
            self._reject(reason)
        else:
            self._accepted(was_stale)

    def torque_command(self, data, time_ns):
        """Take a serialized std_msgs/Float64 motor torque [N m] received at time_ns."""
        was_stale = self.hold.stale
        self._take(self.hold.torque_command(float64_value(data), time_ns), was_stale)

    def velocity_command(self, data, time_ns):
        """Take a serialized std_msgs/Float64 nut velocity [m/s] received at time_ns."""
        was_stale = self.hold.stale
        self._take(self.hold.velocity_command(float64_value(data), time_ns), was_stale)

    def position_command(self, data, time_ns):
        """Take a serialized std_msgs/Float64 nut position [m] received at time_ns."""
        was_stale = self.hold.stale
        self._take(self.hold.position_command(float64_value(data), time_ns), was_stale)

    def joint_commands(self, data, time_ns):
        """Take a serialized sensor_msgs/JointState received at time_ns."""
        msg = deserialize_message(data, JointState)
        was_stale = self.hold.stale
        result, reason = self.hold.joint_commands(msg.name, msg.position, msg.velocity,
                                                  msg.effort, time_ns)
        if result == ACCEPTED:
            self._accepted(was_stale)
        elif result == DROPPED:
            pass
        elif result == IGNORED:
            self.ignored += 1
            if not self._warned_no_joint:
                self._warned_no_joint = True
                self._log.warn(f'joint_commands without joint {self.hold.screw_joint!r} or '
                               f'{self.hold.nut_joint!r} ignored (names {list(msg.name)[:8]}); '
                               'warning once')
        else:
            self._reject(reason)

    def external_force(self, data):
        """Take a serialized std_msgs/Float64 external force [N]."""
        reason = self.hold.external_force(float64_value(data))
        if reason:
            self._reject(reason)

    def command_for_step(self, age_now):
        """
        Return the drive command for the step at ``age_now`` if it changed, else None.

        Logs once when a command goes stale (the drive's reaction: zero torque
        or a quick stop); the next command logs its resumption.

        Parameters
        ----------
        age_now : int
            The step's time [ns] in the time base of the commands.

        """
        hold = self.hold
        was_stale = hold.stale
        command = hold.changed_command(age_now)
        if hold.stale and not was_stale:
            reaction = ('applying 0 N m' if hold.mode == MODE_TORQUE else
                        'quick stop, then holding the position')
            self._log.warn(f'{MODE_NAMES[hold.mode]} command older than command_timeout '
                           f'{hold.timeout:g} s: {reaction} until the next command')
        return command

    def age(self, wall_now, sim_now=None):
        """Return the age [s] of the last drive command as diagnostics show it."""
        if self.cmd_wall is None:
            return 'no command yet'
        if sim_now is None:
            return f'{(wall_now - self.cmd_wall) / NS:.3f}'
        return f'{(sim_now - self.hold.cmd_time) / NS:.3f}'
