"""
The command rules of the axis, shared by the node and ``resim`` so that they cannot drift apart.

- Validation: a non-finite command, an external force beyond the range of the
  ``external_force`` parameter, or a malformed ``joint_commands`` message is
  rejected with a reason and never reaches the model.
- Zero-order hold: a command holds until the next one.
- Timeout: a torque command older than ``command_timeout`` is replaced by 0.
- The log-time rule (:data:`COMMAND_LOG_TIME`): a command logged at t acts on
  the step from t to t + dt, whose states carry the stamp t + dt.

Times are integer nanoseconds in whatever time base the caller uses (wall
clock in the node's realtime mode, sim time otherwise).
"""
import math

from .params import ScrewParams

#: How a recording's log times relate to steps (stored in every parameters record).
COMMAND_LOG_TIME = 'a command logged at t acts on the step [t, t + dt)'

#: Largest |external_force| command [N] taken: the range of the parameter of the same name.
EXTERNAL_FORCE_LIMIT = ScrewParams.field_info()['external_force'][2]['hi']

NS = 1_000_000_000

#: Results of :meth:`CommandHold.joint_commands`.
ACCEPTED, IGNORED, REJECTED = 'accepted', 'ignored', 'rejected'


class CommandHold:
    """
    The held commands of one axis: motor torque [N m] and external force [N].

    Parameters
    ----------
    joint_prefix : str
        Prefix of the joint names; ``joint_commands`` set the effort of
        ``<joint_prefix>screw_joint``.
    timeout : float
        Command timeout [s]; 0 disables it.

    """

    def __init__(self, joint_prefix='', timeout=0.0):
        """Start with no command: zero torque and force."""
        self.screw_joint = joint_prefix + 'screw_joint'
        self.timeout = float(timeout)
        self.reset()

    def reset(self):
        """Forget every command (as after ``~/reset``)."""
        self.torque = 0.0
        self.force = 0.0
        self.cmd_time = None        # time of the last torque command [ns], None: none yet
        self.stale = False

    def torque_command(self, value, time_ns):
        """
        Hold a motor torque command; return a rejection reason or None.

        Clears ``stale``; the caller can tell a resumed command from ``stale``
        before the call.

        Parameters
        ----------
        value : float
            Motor torque [N m], theta sense.
        time_ns : int
            Time of the command [ns], the base of its age.

        """
        if not math.isfinite(value):
            return f'non-finite torque_command {value!r}'
        self.torque = value
        self.cmd_time = time_ns
        self.stale = False
        return None

    def joint_commands(self, names, efforts, time_ns):
        """
        Apply a ``joint_commands`` message given its names and efforts.

        Returns ``(result, reason)``: :data:`ACCEPTED`, :data:`IGNORED` (the
        message does not name our joint) or :data:`REJECTED` with the reason.

        Parameters
        ----------
        names : sequence of str
            The message's joint names.
        efforts : sequence of float
            The message's efforts [N m for the screw joint].
        time_ns : int
            Time of the command [ns].

        """
        joint = self.screw_joint
        count = list(names).count(joint)
        if count == 0:
            return IGNORED, f'joint_commands without joint {joint!r}'
        if count > 1:
            return REJECTED, f'joint_commands naming {joint!r} {count} times'
        if len(efforts) != len(names):
            return REJECTED, (f'joint_commands with {len(efforts)} efforts for '
                              f'{len(names)} names')
        value = float(efforts[list(names).index(joint)])
        if not math.isfinite(value):
            return REJECTED, f'non-finite joint_commands effort {value!r}'
        self.torque_command(value, time_ns)
        return ACCEPTED, None

    def external_force(self, value):
        """
        Hold an external force command; return a rejection reason or None.

        Parameters
        ----------
        value : float
            Axial force on the nut along +x [N].

        """
        # A finite but huge force (1e308 N) would drive the state to Inf and stop
        # the integration: refuse what the parameter range refuses.
        if not abs(value) <= EXTERNAL_FORCE_LIMIT:
            return (f'external_force {value!r} N outside '
                    f'[-{EXTERNAL_FORCE_LIMIT:g}, {EXTERNAL_FORCE_LIMIT:g}] N')
        self.force = value
        return None

    def applied_torque(self, now_ns):
        """
        Return the motor torque [N m] to apply at ``now_ns``: the held one, or 0 once stale.

        Sets ``stale`` when the held torque command is older than the timeout.

        Parameters
        ----------
        now_ns : int
            The current time [ns], in the time base of the commands.

        """
        if self.cmd_time is not None and self.timeout > 0.0 and (
                now_ns - self.cmd_time) > self.timeout * NS:
            self.stale = True
            return 0.0
        return self.torque


def first_step(log_time_ns, t0_ns, dt_ns):
    """Return k of the step [t0 + k dt, t0 + (k + 1) dt) that a command logged then acts on."""
    return -((t0_ns - log_time_ns) // dt_ns)
