"""The inputs of ``simulate``: torque, drive (velocity, position) and force sources, CSV series."""
import bisect
import math

import numpy as np

from ..options import check_finite, parse_options, RunError
from ...core.commands import CommandHold


def read_csv_series(path, what):
    """Read ``time,value`` rows (s, SI) with an optional header; return sorted (times, values)."""
    try:
        fh = open(path, newline='')
    except OSError as exc:
        raise RunError(f'{what} CSV {path}: {exc.strerror or exc}') from None
    times, values = [], []
    with fh:
        for lineno, line in enumerate(fh, 1):
            text = line.strip()
            if not text or text.startswith('#'):
                continue
            cells = [c.strip() for c in text.replace(';', ',').split(',')]
            try:
                if len(cells) != 2:
                    raise ValueError
                t, v = float(cells[0]), float(cells[1])
            except ValueError:
                if not times and lineno == 1 and not _numeric(cells[0]):
                    continue                        # header line
                raise RunError(f'{what} CSV {path}, line {lineno}: expected "time,value" '
                               f'with two numbers, got {text[:60]!r}') from None
            if not (math.isfinite(t) and math.isfinite(v)):
                raise RunError(f'{what} CSV {path}, line {lineno}: non-finite number')
            if times and t < times[-1]:
                raise RunError(f'{what} CSV {path}, line {lineno}: time {t} s goes backwards '
                               f'(previous {times[-1]} s)')
            times.append(t)
            values.append(v)
    if not times:
        raise RunError(f'{what} CSV {path}: no data rows')
    return times, values


def _numeric(text):
    try:
        float(text)
        return True
    except ValueError:
        return False


class Held:
    """
    Zero-order hold of a (time, value) series: value of the last row with time <= t.

    Parameters
    ----------
    times : list of float
        Sorted times [s].
    values : list of float
        Values (SI) at those times.
    before : float
        Value before the first row.

    """

    def __init__(self, times, values, before=0.0):
        """Keep the series."""
        self.times, self.values, self.before = times, values, before

    def __call__(self, t):
        """Return the held value at time t [s]."""
        i = bisect.bisect_right(self.times, t + 1e-12)
        return self.values[i - 1] if i else self.before

    def block(self, ts):
        """Return the held values at the times ``ts`` [s] (an array), as ``__call__`` each."""
        i = np.searchsorted(np.asarray(self.times, dtype=float), ts + 1e-12, side='right')
        values = np.concatenate([[self.before], np.asarray(self.values, dtype=float)])
        return values[i]


class TorqueSource:
    """
    An open-loop torque input: ``fn(t) -> torque [N m]`` and its vectorised form.

    Called as ``source(k, t, x, v)`` like every torque source (tick, time [s],
    nut position [m], nut velocity [m/s]); ``block(ts)`` returns the torques
    at the times ``ts`` [s] with the same doubles.
    """

    def __init__(self, scalar, vector):
        """Keep ``scalar(t)`` and ``vector(ts)``."""
        self.scalar, self.block = scalar, vector

    def __call__(self, k, t, x, v):
        """Return the torque [N m] at time t [s]."""
        return self.scalar(t)


class MoveController:
    """
    PID position control of the nut toward a target along a ramp reference (the profile ``move``).

    Reference: from the initial position to ``target`` at ``speed`` m/s.
    Gains from the effective moving mass M (payload + reflected inertia) with
    three closed-loop poles at ``-2 pi bandwidth``: kd = 3 M w, kp = 3 M w^2,
    ki = M w^3; gravity feed-forward; the integral is clamped so its force
    stays within the motor's max_torque (anti-windup). The model saturates the
    torque itself.

    Parameters
    ----------
    params : ScrewParams
        The physics of the axis.
    target : float
        Target nut position [m].
    speed : float
        Reference speed [m/s].
    bandwidth : float
        Closed-loop bandwidth [Hz].

    """

    def __init__(self, params, target, speed, bandwidth=3.0):
        """Precompute the reference ramp and the gains."""
        self.x0 = params.initial_position
        self.target = target
        self.speed = abs(speed)
        self.rt = params.lead_ratio
        mass = params.moving_mass + (params.motor_inertia + params.screw_inertia) / self.rt ** 2
        w = 2.0 * math.pi * bandwidth
        self.kp, self.kd, self.ki = 3.0 * mass * w * w, 3.0 * mass * w, mass * w ** 3
        self.f_grav = params.moving_mass * params.gravity * math.sin(params.inclination)
        self.f_max = params.max_torque / self.rt
        self.hs = params.hand_sign
        self.integral = 0.0
        self.t_prev = 0.0

    def reference(self, t):
        """Return the reference position [m] at time t [s]."""
        d = self.target - self.x0
        travel = self.speed * t
        return self.target if travel >= abs(d) else self.x0 + math.copysign(travel, d)

    def __call__(self, t, x, v):
        """
        Return the motor torque [N m] for the nut position x [m].

        v is the motor velocity expressed as nut velocity (h rt omega_m) [m/s]:
        damping on the motor side is collocated with the torque, so a compliant
        coupling does not destabilize the loop.
        """
        ref = self.reference(t)
        v_ref = 0.0 if ref == self.target else math.copysign(self.speed, self.target - self.x0)
        err = ref - x
        lim = self.f_max / self.ki
        self.integral = min(lim, max(-lim, self.integral + err * (t - self.t_prev)))
        self.t_prev = t
        force = self.kp * err + self.kd * (v_ref - v) + self.ki * self.integral + self.f_grav
        # x = rt * q and q = h * theta: a force F along +x needs a torque h * rt * F.
        return self.hs * self.rt * force


def excite_profile(args, params):
    """Return the identification profile of the ``excite`` option (None without it)."""
    if getattr(args, 'excite', None) is None:
        if getattr(args, 'excite_opt', None):
            raise RunError('<<excite_opt>> needs <<excite>> PROFILE')
        return None
    from ...analysis.excitation.profiles import make_profile
    return make_profile(args.excite, params, **parse_options(args.excite_opt, 'excite_opt'))


def make_torque_source(args, params, profile=None):
    """
    Return ``fn(k, t, x, v) -> torque`` and a description of the input.

    x is the nut position [m], v the motor velocity as nut velocity [m/s];
    ``fn.needs_state`` marks a closed loop (stepped tick by tick).
    ``profile``: the ``excite`` option's profile, a torque input here.
    """
    chosen = [n for n, v in (('<<torque>>', args.torque), ('<<torque_csv>>', args.torque_csv),
                             ('<<profile>>', args.profile)) if v is not None]
    if profile is not None:
        chosen.append('<<excite>>')
    if len(chosen) > 1:
        raise RunError(f'give only one torque input, not {" and ".join(chosen)}')
    if profile is not None:
        return profile.torque_source(), profile.describe()
    if args.torque_csv is not None:
        held = Held(*read_csv_series(args.torque_csv, 'torque'))
        return TorqueSource(held, held.block), f'torque_csv={args.torque_csv}'
    if args.profile is None:
        c = float(args.torque or 0.0)
        check_finite('torque', c)
        return TorqueSource(lambda t: c, lambda ts: np.full(len(ts), c)), f'torque={c}'
    if args.profile == 'move':
        return _move_source(args, params)
    amp = 0.5 * params.max_torque if args.amplitude is None else args.amplitude
    check_finite('amplitude', amp)
    f = args.frequency
    if args.profile == 'step':
        t_step = args.step_time
        return TorqueSource(lambda t: amp if t >= t_step else 0.0,
                            lambda ts: np.where(ts >= t_step, amp, 0.0)), (
            f'profile=step amplitude={amp} step_time={t_step}')
    if args.profile == 'ramp':
        dur = args.duration
        return TorqueSource(lambda t: amp * t / dur, lambda ts: amp * ts / dur), (
            f'profile=ramp amplitude={amp}')
    w = 2.0 * math.pi * f
    return TorqueSource(lambda t: amp * math.sin(w * t), lambda ts: amp * np.sin(w * ts)), (
        f'profile=sine amplitude={amp} f={f}')


def _move_source(args, params):
    """Return the closed-loop torque source of the profile ``move`` and its description."""
    target = args.target if args.target is not None else params.initial_position + 0.01
    if not params.stroke_min <= target <= params.stroke_max:
        raise RunError(f'<<target>> {target} m lies outside the stroke '
                       f'[{params.stroke_min}, {params.stroke_max}] m')
    ctl = MoveController(params, target, args.speed)

    def fn(k, t, x, v):
        """Return the torque [N m] at tick k, time t [s], nut position x [m], velocity v."""
        return ctl(t, x, v)
    fn.needs_state = True
    return fn, f'profile=move target={target} speed={args.speed}'


def make_force_source(args):
    """Return ``fn(t) -> external force [N]`` (None: no force input) and a description."""
    if args.force is not None and args.force_csv is not None:
        raise RunError('give only one of <<force>> and <<force_csv>>')
    if args.force_csv is not None:
        times, values = read_csv_series(args.force_csv, 'force')
        for t, v in zip(times, values):
            _check_force(f'force CSV {args.force_csv}, t={t} s', v)
        return Held(times, values), f'force_csv={args.force_csv}'
    if args.force is not None:
        check_finite('force', args.force)
        c = float(args.force)
        _check_force('<<force>>', c)
        return Held([], [], before=c), f'force={c}'
    return None, ''


def _check_force(what, value):
    """Raise RunError for an external force [N] the node's command rules reject."""
    reason = CommandHold().external_force(value)
    if reason is not None:
        raise RunError(f'{what}: {reason}')


class ProfileSeries:
    """An excitation profile as a series: ``series(t)`` and ``series.block(ts)`` [s]."""

    def __init__(self, profile):
        """Keep the profile."""
        self.profile = profile

    def __call__(self, t):
        """Return the command value at time t [s]."""
        return self.profile(t)

    def block(self, ts):
        """Return the command values at the times ``ts`` [s]."""
        return self.profile.values(ts)


class DriveSource:
    """
    A drive input: ``source(t) -> (nut position [m] or NaN, nut velocity [m/s] or NaN)``.

    ``block(ts)`` returns the two arrays at the times ``ts`` [s] with the same doubles.
    """

    def __init__(self, position, velocity):
        """Keep the position and velocity inputs: each a Held series, a float or None."""
        self.position, self.velocity = position, velocity

    @staticmethod
    def _at(value, t):
        if value is None:
            return math.nan
        return value(t) if callable(value) else value

    @staticmethod
    def _block(value, ts):
        if value is None or not callable(value):
            return np.full(len(ts), math.nan if value is None else value)
        return value.block(ts)

    def __call__(self, t):
        """Return (position [m], velocity [m/s]) at time t [s]."""
        return self._at(self.position, t), self._at(self.velocity, t)

    def block(self, ts):
        """Return (positions [m], velocities [m/s]) at the times ``ts`` [s]."""
        return self._block(self.position, ts), self._block(self.velocity, ts)


class Trapezoid:
    """
    A trapezoidal move of the nut from ``x0`` to ``target``: position [m] and velocity [m/s].

    Accelerates at ``accel`` to ``speed``, cruises, decelerates to rest at the
    target (a triangle when the distance is too short to reach ``speed``).
    """

    def __init__(self, x0, target, speed, accel):
        """Precompute the phases."""
        self.x0, self.d = x0, target - x0
        self.sign = 1.0 if self.d >= 0 else -1.0
        dist = abs(self.d)
        self.a = accel
        self.v = min(speed, math.sqrt(dist * accel))        # peak speed
        self.t1 = self.v / accel                            # end of acceleration
        self.t2 = self.t1 + (dist - self.v * self.t1) / self.v if self.v > 0 else 0.0
        self.t3 = self.t2 + self.t1                         # at the target

    def __call__(self, t):
        """Return (position [m], velocity [m/s]) at time t [s]."""
        a, v, t1, t2, t3 = self.a, self.v, self.t1, self.t2, self.t3
        if t <= 0.0:
            s, w = 0.0, 0.0
        elif t < t1:
            s, w = 0.5 * a * t * t, a * t
        elif t < t2:
            s, w = 0.5 * v * t1 + v * (t - t1), v
        elif t < t3:
            r = t3 - t
            s, w = abs(self.d) - 0.5 * a * r * r, a * r
        else:
            s, w = abs(self.d), 0.0
        return self.x0 + self.sign * s, self.sign * w


def make_drive_source(args, params, profile=None):
    """
    Return the drive input of simulate as (fn, topic, description), or None for a torque input.

    ``profile``: the ``excite`` option's profile (a drive input when it commands
    velocity or position; the commission profile is returned as it is, with
    topic ``mixed``: each part on its own command topic).

    ``fn(t)`` returns (nut position [m] or NaN, nut velocity [m/s] or NaN) at t [s];
    ``topic`` is the command topic it is recorded on: ``velocity_command``,
    ``position_command``, or ``joint_commands`` (nut joint position and velocity
    feed-forward, for the trapezoidal move).
    """
    chosen = [n for n, v in (('<<velocity>>', args.velocity),
                             ('<<velocity_csv>>', args.velocity_csv),
                             ('<<position>>', args.position),
                             ('<<position_csv>>', args.position_csv))
              if v is not None]
    if profile is not None and profile.kind == 'mixed':     # commission: a part per command
        others = chosen + [n for n, v in (('<<torque>>', args.torque),
                                          ('<<torque_csv>>', args.torque_csv),
                                          ('<<profile>>', args.profile)) if v is not None]
        if others:
            raise RunError(f'give only one input, not <<excite>> and {" and ".join(others)}')
        return profile, 'mixed', profile.describe()
    if args.profile == 'trapezoid':
        chosen.append('<<profile>> trapezoid')
    if profile is not None and profile.kind != 'torque':
        chosen.append('<<excite>>')
    torque = [n for n, v in (('<<torque>>', args.torque), ('<<torque_csv>>', args.torque_csv))
              if v is not None]
    if args.profile not in (None, 'trapezoid'):
        torque.append(f'<<profile>> {args.profile}')
    if params.drive_type == 'stepper':
        if profile is not None and profile.kind == 'torque':
            torque.append('<<excite>>')
        if torque:
            raise RunError(f'{" and ".join(torque)}: a stepper axis (drive_type stepper) takes '
                           'position and velocity inputs only; torque inputs are refused')
        if not chosen:            # no input: the driver holds the initial position
            x0 = params.initial_position
            return DriveSource(x0, None), 'position_command', f'position={x0} (hold)'
    if not chosen:
        return None
    if len(chosen) + len(torque) > 1:
        raise RunError(f'give only one input, not {" and ".join(chosen + torque)}')
    if profile is not None:
        held = ProfileSeries(profile)
        source = DriveSource(held, None) if profile.kind == 'position' else DriveSource(
            None, held)
        return source, profile.topic, profile.describe()
    if args.velocity is not None:
        c = float(args.velocity)
        check_finite('velocity', c)
        return DriveSource(None, c), 'velocity_command', f'velocity={c}'
    if args.position is not None:
        c = float(args.position)
        check_finite('position', c)
        _check_stroke('<<position>>', c, params)
        return DriveSource(c, None), 'position_command', f'position={c}'
    if args.velocity_csv is not None:
        held = Held(*read_csv_series(args.velocity_csv, 'velocity'))
        return (DriveSource(None, held), 'velocity_command',
                f'velocity_csv={args.velocity_csv}')
    if args.position_csv is not None:
        times, values = read_csv_series(args.position_csv, 'position')
        for v in values:
            _check_stroke(f'position CSV {args.position_csv}', v, params)
        held = Held(times, values, before=params.initial_position)
        return (DriveSource(held, None), 'position_command',
                f'position_csv={args.position_csv}')
    target = args.target if args.target is not None else params.initial_position + 0.01
    _check_stroke('<<target>>', target, params)
    for name, value in (('speed', args.speed), ('accel', args.accel)):
        check_finite(name, value)
        if not value > 0:
            raise RunError(f'<<{name}>> {value} must be > 0')
    move = Trapezoid(params.initial_position, target, args.speed, args.accel)
    return move, 'joint_commands', (f'profile=trapezoid target={target} speed={args.speed} '
                                    f'accel={args.accel}')


def _check_stroke(what, x, params):
    if not params.stroke_min <= x <= params.stroke_max:
        raise RunError(f'{what} {x} m lies outside the stroke '
                       f'[{params.stroke_min}, {params.stroke_max}] m')
