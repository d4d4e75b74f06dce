"""
The command rules of the axis, shared by the node and ``resim`` so that they cannot drift apart.

- Modes, as a servo drive has them (CiA 402 cyclic synchronous torque,
  velocity, position): the last command sets the mode. In a ``joint_commands``
  message a finite position makes a position command (a finite velocity and
  effort of the same joint are its feed-forwards); else a finite velocity a
  velocity command (the effort its feed-forward); else an effort a torque
  command. NaN means "not commanded", an empty array likewise.
- Joints by name: ``<prefix>screw_joint`` (rad, rad/s, N m) or
  ``<prefix>nut_joint`` (m, m/s, N), mapped to the motor through the lead
  (:class:`NutMap`), referenced so that the initial nut position maps to the
  initial motor angle, as after homing.
- Separate messages per interface in one tick (a position message, then a
  velocity message, as some ros2_control hardware interfaces publish them)
  merge into one command: a field a later message leaves NaN keeps the value
  an earlier message of the same tick gave it. With a fixed
  ``joint_command_mode`` (the command interface a ros2_control URDF
  declares) the mode never changes: a message without the mode's main field
  only updates the feed-forwards, whenever it comes.
- Validation: a non-finite (other than NaN) or malformed command, or an
  external force beyond the range of the ``external_force`` parameter, is
  rejected with a reason and never reaches the model; so is a torque command
  (``torque_command``, or a ``joint_commands`` effort command) to a stepper.
- Zero-order hold, and a timeout per mode, like a drive's reaction to a loss
  of communication: a stale torque command goes to 0 N m, a stale velocity
  command to a quick stop (ramp to zero, then hold the position), a position
  target holds.
- The log-time rule (:data:`COMMAND_LOG_TIME`): a command logged at t acts on
  the step from t to t + dt, whose states carry the stamp t + dt.
- Injected communication faults: a share ``drop_rate`` of the drive commands
  is lost on arrival (seeded: the n-th command received since start is lost
  when :func:`.sensors.uniform` of n is below the rate; external_force is a
  physical input and never lost), and every drive command reaches the drive
  ``delay`` steps after the step it arrived for.

Times are integer nanoseconds in whatever time base the caller uses (wall
clock in the node's realtime mode, sim time otherwise). Angles and torques
are in the screw joint's sense (theta).
"""
import collections
import math

import numpy as np

from .drive_modes import MODE_NAMES, MODE_POSITION, MODE_QUICKSTOP, MODE_TORQUE, MODE_VELOCITY
from .params import ScrewParams

#: How a recording's log times relate to steps (stored in every parameters record).
COMMAND_LOG_TIME = 'a command logged at t acts on the step [t, t + dt)'

#: Largest |external_force| command [N] taken: the range of the parameter of the same name.
EXTERNAL_FORCE_LIMIT = ScrewParams.field_info()['external_force'][2]['hi']

NS = 1_000_000_000
NAN = float('nan')

#: Values of the run setting joint_command_mode -> fixed mode (None: the mode rule).
JOINT_COMMAND_MODES = {'auto': None, 'position': MODE_POSITION, 'velocity': MODE_VELOCITY,
                       'effort': MODE_TORQUE}

#: Results of :meth:`CommandHold.joint_commands`; DROPPED is also the reason the other
#: command methods return for a command lost to ``drop_rate``.
ACCEPTED, IGNORED, REJECTED, DROPPED = 'accepted', 'ignored', 'rejected', 'dropped'

#: The drive command a model holds after reset: torque mode, 0 N m (a stepper: a hold).
INITIAL_COMMAND = (MODE_TORQUE, NAN, NAN, 0.0)

#: Why a stepper drive refuses a torque command.
STEPPER_TORQUE = ('torque commands are refused: a stepper drive (drive_type stepper) takes '
                  'position and velocity commands only')


class NutMap:
    """
    Nut commands in motor terms: theta = theta0 + k (x - x0), k = h 2 pi / l [rad/m].

    Parameters
    ----------
    theta0 : float
        Motor (screw joint) angle of the reference [rad].
    x0 : float
        Nut position of the reference [m].
    k : float
        Motor angle per nut travel, h 2 pi / l [rad/m] (h = -1 right hand, +1 left).

    """

    def __init__(self, theta0=0.0, x0=0.0, k=-2.0 * math.pi / 0.003):
        """Keep the reference and the scale."""
        self.theta0, self.x0, self.k = float(theta0), float(x0), float(k)

    @classmethod
    def of_model(cls, model):
        """
        Return the map of a model, referenced at its initial state (as after homing).

        Parameters
        ----------
        model : leadscrew_sim.core.model.LeadScrewModel
            The axis; its current state must be the initial one.

        """
        p = model.params
        return cls(model.output().motor_angle, p.initial_position,
                   p.hand_sign * 2.0 * math.pi / p.lead)

    def position(self, x):
        """Return the motor angle [rad] of nut position ``x`` [m]."""
        return self.theta0 + self.k * (x - self.x0)

    def velocity(self, v):
        """Return the motor velocity [rad/s] of nut velocity ``v`` [m/s]."""
        return self.k * v

    def effort(self, f):
        """Return the motor torque [N m] of an axial force ``f`` [N] (ideal: T = F / k)."""
        return f / self.k


def _value(values, i):
    return float(values[i]) if len(values) else NAN


class CommandHold:
    """
    The held commands of one axis: the drive command and the external force [N].

    Parameters
    ----------
    joint_prefix : str
        Prefix of the joint names ``<prefix>screw_joint`` and ``<prefix>nut_joint``.
    timeout : float
        Command timeout [s]; 0 disables it.
    nut_map : NutMap, optional
        How nut commands map to the motor (default: a right-hand 3 mm lead from 0).
    joint_command_mode : str
        A key of :data:`JOINT_COMMAND_MODES`: ``'auto'`` (the mode rule) or the
        fixed mode of ``joint_commands``.
    params : ScrewParams, optional
        Its ``command_delay`` [ticks], ``fault_command_drop_rate`` and
        ``sensor_seed`` (default: none, no loss); see :meth:`set_faults`.

    """

    def __init__(self, joint_prefix='', timeout=0.0, nut_map=None, joint_command_mode='auto',
                 params=None):
        """Start with no command: torque mode, zero torque and force."""
        self.set_joint_prefix(joint_prefix)
        self.timeout = float(timeout)
        self.nut_map = nut_map if nut_map is not None else NutMap()
        self.joint_mode = JOINT_COMMAND_MODES[joint_command_mode]
        self.received = 0           # drive commands received since start (the drop counter)
        self.dropped = 0            # of them lost to drop_rate
        self.delay, self.drop_rate, self.seed = 0, 0.0, 0
        self.stepper = False        # a stepper drive refuses torque commands
        if params is not None:
            self.set_faults(params)
        self.reset()

    def set_faults(self, params):
        """
        Take the delay and the loss of commands from a parameter set.

        Parameters
        ----------
        params : ScrewParams
            ``command_delay`` [ticks], ``fault_command_drop_rate`` (0..1) and
            ``sensor_seed``; and ``drive_type``: a stepper refuses torque commands.

        """
        self.delay = int(params.command_delay)
        self.drop_rate = float(params.fault_command_drop_rate)
        self.seed = int(params.sensor_seed)
        self.stepper = params.drive_type == 'stepper'

    def _lost(self):
        """Count a received drive command; return True if drop_rate loses it."""
        n = self.received
        self.received += 1
        if self.drop_rate <= 0.0:
            return False
        from .engine.sensors import STREAM_COMMAND_DROP, uniform
        if uniform(self.seed, STREAM_COMMAND_DROP, n) < self.drop_rate:
            self.dropped += 1
            return True
        return False

    def set_joint_prefix(self, joint_prefix):
        """
        Follow a change of the joint name prefix.

        Parameters
        ----------
        joint_prefix : str
            The new prefix of ``screw_joint`` and ``nut_joint``.

        """
        self.screw_joint = joint_prefix + 'screw_joint'
        self.nut_joint = joint_prefix + 'nut_joint'

    def reset(self):
        """Forget every command (as after ``~/reset``)."""
        self.mode = MODE_TORQUE
        self.position = NAN         # motor angle target [rad]
        self.velocity = NAN         # motor velocity command or feed-forward [rad/s]
        self.effort = 0.0           # motor torque command or feed-forward [N m]
        self.force = 0.0
        self.cmd_time = None        # time of the last drive command [ns], None: none yet
        self.stale = False
        self._tick = None           # (time_ns, position, velocity, effort) merged this tick
        self._version = getattr(self, '_version', 0) + 1     # counts command changes
        self._delivered = None      # (version, stale) of the last changed_command()
        self._line = collections.deque()    # commands of the last steps, for the delay

    @property
    def torque(self):
        """Return the held motor torque command [N m] (torque mode) or feed-forward."""
        return self.effort

    def _set(self, mode, position, velocity, effort, time_ns):
        self.mode, self.position, self.velocity = mode, position, velocity
        self.effort = effort if math.isfinite(effort) else 0.0
        self.cmd_time = time_ns
        self.stale = False
        self._version += 1

    def torque_command(self, value, time_ns):
        """
        Take a motor torque command; return a rejection reason or None.

        Clears ``stale``; the caller can tell a resumed command from ``stale``
        before the call.

        Parameters
        ----------
        value : float
            Motor torque [N m], theta sense.
        time_ns : int
            Time of the command [ns], the base of its age.

        """
        if self._lost():
            return DROPPED
        if not math.isfinite(value):
            return f'non-finite torque_command {value!r}'
        if self.stepper:
            return STEPPER_TORQUE
        self._set(MODE_TORQUE, NAN, NAN, value, time_ns)
        return None

    def velocity_command(self, value, time_ns):
        """
        Take a nut velocity command; return a rejection reason or None.

        Parameters
        ----------
        value : float
            Nut velocity [m/s].
        time_ns : int
            Time of the command [ns].

        """
        if self._lost():
            return DROPPED
        if not math.isfinite(value):
            return f'non-finite velocity_command {value!r}'
        self._set(MODE_VELOCITY, NAN, self.nut_map.velocity(value), 0.0, time_ns)
        return None

    def position_command(self, value, time_ns):
        """
        Take a nut position command; return a rejection reason or None.

        Parameters
        ----------
        value : float
            Nut position target [m].
        time_ns : int
            Time of the command [ns].

        """
        if self._lost():
            return DROPPED
        if not math.isfinite(value):
            return f'non-finite position_command {value!r}'
        self._set(MODE_POSITION, self.nut_map.position(value), NAN, 0.0, time_ns)
        return None

    def joint_commands(self, names, positions, velocities, efforts, time_ns):
        """
        Apply a ``joint_commands`` message given its names and arrays.

        Returns ``(result, reason)``: :data:`ACCEPTED`, :data:`IGNORED` (the
        message names neither joint), :data:`DROPPED` (lost to ``drop_rate``)
        or :data:`REJECTED` with the reason.

        Parameters
        ----------
        names : sequence of str
            The message's joint names.
        positions, velocities, efforts : sequence of float
            Its arrays: empty, or one value per name; NaN for "not commanded".
            Screw joint in rad, rad/s, N m; nut joint in m, m/s, N.
        time_ns : int
            Time of the command [ns].

        """
        if self._lost():
            return DROPPED, DROPPED
        names = list(names)
        for what, values in (('positions', positions), ('velocities', velocities),
                             ('efforts', efforts)):
            if len(values) and len(values) != len(names):
                return REJECTED, (f'joint_commands with {len(values)} {what} for '
                                  f'{len(names)} names')
        counts = (names.count(self.screw_joint), names.count(self.nut_joint))
        if counts == (0, 0):
            return IGNORED, f'joint_commands without joint {self.screw_joint!r}'
        if max(counts) > 1:
            joint = self.screw_joint if counts[0] > 1 else self.nut_joint
            return REJECTED, f'joint_commands naming {joint!r} {max(counts)} times'
        if counts == (1, 1):
            return REJECTED, (f'joint_commands for both {self.screw_joint!r} and '
                              f'{self.nut_joint!r}: command one of them')
        nut = counts[1] == 1
        i = names.index(self.nut_joint if nut else self.screw_joint)
        p, v, e = _value(positions, i), _value(velocities, i), _value(efforts, i)
        for what, x in (('position', p), ('velocity', v), ('effort', e)):
            if math.isinf(x):
                return REJECTED, f'non-finite joint_commands {what} {x!r}'
        if nut:
            m = self.nut_map
            p, v, e = m.position(p), m.velocity(v), m.effort(e)
        if self._tick is not None and self._tick[0] == time_ns:     # merge within a tick
            _t, p0, v0, e0 = self._tick
            p, v, e = (p if p == p else p0), (v if v == v else v0), (e if e == e else e0)
        if not (p == p or v == v or e == e):
            return REJECTED, 'joint_commands commanding nothing (all values NaN or empty)'
        mode = self.joint_mode
        if mode is None:
            mode = MODE_POSITION if p == p else (MODE_VELOCITY if v == v else MODE_TORQUE)
        if mode == MODE_TORQUE and self.stepper:
            return REJECTED, f'joint_commands effort: {STEPPER_TORQUE}'
        elif (p, v, e)[(MODE_POSITION, MODE_VELOCITY, MODE_TORQUE).index(mode)] != \
                (p, v, e)[(MODE_POSITION, MODE_VELOCITY, MODE_TORQUE).index(mode)]:
            # a feed-forward update: the mode's main command stays
            if self.mode != mode or self.cmd_time is None:
                return REJECTED, (f'joint_commands without a {MODE_NAMES[mode]} (the '
                                  'joint_command_mode) before any')
            if mode == MODE_POSITION:
                p = self.position
            elif mode == MODE_VELOCITY:
                v = self.velocity
            else:
                e = self.effort
        self._tick = (time_ns, p, v, e)
        self._set(mode, p, v, e, time_ns)
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

    def take_series(self, kind, values, times_ns):
        """
        Take one Float64 drive command per step at once; return the drive commands, or None.

        The vectorised form of calling ``kind`` with ``values[i]`` at
        ``times_ns[i]`` and :meth:`command_at` right after each: rows of the
        same doubles. Returns None and takes nothing when a value is not
        finite or commands may be lost or delayed (take them one by one then).

        Parameters
        ----------
        kind : str
            ``'torque_command'`` [N m], ``'velocity_command'`` [m/s] or
            ``'position_command'`` [m].
        values : array_like of float
            The commands, one per step.
        times_ns : array_like of int
            Their times [ns].

        Returns
        -------
        numpy.ndarray, shape (n, 4), or None
            (mode, position [rad], velocity [rad/s], effort [N m]) per step.

        """
        v = np.asarray(values, dtype=float)
        if self.delay > 0 or self.drop_rate > 0.0 or not len(v) or not np.isfinite(v).all() \
                or (self.stepper and kind == 'torque_command'):
            return None
        rows = np.empty((len(v), 4))
        m = self.nut_map
        if kind == 'torque_command':
            rows[:] = (MODE_TORQUE, NAN, NAN, 0.0)
            rows[:, 3] = v
        elif kind == 'velocity_command':
            rows[:] = (MODE_VELOCITY, NAN, 0.0, 0.0)
            rows[:, 2] = m.k * v
        elif kind == 'position_command':
            rows[:] = (MODE_POSITION, 0.0, NAN, 0.0)
            rows[:, 1] = m.theta0 + m.k * (v - m.x0)
        else:
            raise ValueError(f'unknown Float64 drive command {kind!r}')
        self.received += len(v) - 1
        getattr(self, kind)(float(v[-1]), int(times_ns[-1]))
        return rows

    def command_at(self, now_ns):
        """
        Return the drive command (mode, position [rad], velocity [rad/s], effort [N m]) at now.

        Applies the timeout of the mode and sets ``stale``: a stale torque
        command becomes 0 N m, a stale velocity command a quick stop; a
        position target holds.

        Parameters
        ----------
        now_ns : int
            The current time [ns], in the time base of the commands.

        """
        mode = self.mode
        if mode != MODE_POSITION and self.cmd_time is not None and self.timeout > 0.0 and (
                now_ns - self.cmd_time) > self.timeout * NS:
            self.stale = True
            if mode == MODE_TORQUE:
                return MODE_TORQUE, NAN, NAN, 0.0
            return MODE_QUICKSTOP, NAN, 0.0, 0.0
        return mode, self.position, self.velocity, self.effort

    def changed_command(self, now_ns):
        """
        Return the drive command at now if it changed since the last call, else None.

        The model holds the drive command in its state, so the node and
        ``resim`` hand it over only when a command arrived or timed out: a
        quick stop then runs its course in the drive instead of restarting
        every tick.

        Parameters
        ----------
        now_ns : int
            The current time [ns], in the time base of the commands.

        """
        command = self.command_at(now_ns)
        key = (self._version, self.stale)
        if key == self._delivered:
            command = None
        self._delivered = key
        return self.delayed(command)

    def delayed(self, command):
        """
        Return the command of ``delay`` steps ago: call once per step with this step's.

        Parameters
        ----------
        command : tuple or None
            This step's drive command (None: no change), or any per-step value.

        """
        if self.delay <= 0:
            if self._line:
                self._line.clear()
            return command
        line = self._line
        line.append(command)
        out = None
        while len(line) > self.delay:   # more than one after a shorter delay: the newest
            older = line.popleft()
            out = older if older is not None else out
        return out


def first_step(log_time_ns, t0_ns, dt_ns):
    """Return k of the step [t0 + k dt, t0 + (k + 1) dt) that a command logged then acts on."""
    return -((t0_ns - log_time_ns) // dt_ns)
