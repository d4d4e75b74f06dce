"""
The machinery of the excitation profiles: options, segments, values and the command sources.

A profile (:mod:`.excitation` has the four) is a piecewise-linear sequence of
:class:`Segment` s built from options that carry a unit and a range; this
module checks the options, evaluates the segments on one time or an array
of times with the same arithmetic, and hands the profile to ``simulate``
(torque source, drive source) and to the exciter node (``controller``).
"""
import bisect
import collections
import math

import numpy as np

from ...core.fields import ParameterError

__all__ = ['Builder', 'KIND_TOPICS', 'Profile', 'ProfileError', 'Segment', 'STROKE_MARGIN',
           'UNITS', 'check_speed', 'nut_speed_limit', 'stroke_room']

#: Command kind -> the node's command topic of its values (their unit: UNITS).
KIND_TOPICS = {'torque': 'torque_command', 'velocity': 'velocity_command',
               'position': 'position_command'}
#: Command kind -> the unit of its values.
UNITS = {'torque': 'N m', 'velocity': 'm/s', 'position': 'm'}

#: Share of the stroke length kept clear of each end stop by the moves.
STROKE_MARGIN = 0.02

#: One piece of a profile: the command runs linearly from v0 (at t0) to v1 (at t1)
#: [s, command unit]; label names it, direction is +1, -1 or 0.
Segment = collections.namedtuple('Segment', 't0 t1 v0 v1 label direction')


class ProfileError(ParameterError):
    """A profile option outside its range: one line naming profile, option, value and range."""

    def __init__(self, profile, option, message, text=None):
        """Keep the names; the message reads ``excitation 'profile': option 'x' ...``."""
        ValueError.__init__(self, text or f"excitation '{profile}': option '{option}' {message}")
        self.name = option
        self.profile = profile


class Profile:
    """
    Base of the profiles: validated options, segments, vectorised values.

    Parameters
    ----------
    params : ScrewParams
        The axis; the defaults of the options and their limits come from it.
    **options
        Options of the profile by name (see ``OPTIONS`` of the class), SI units.

    """

    name = ''
    kind = ''
    summary = ''
    #: option -> (unit, description, lower bound, upper bound, integer).
    OPTIONS = {}

    def __init__(self, params, **options):
        """Validate the options, build the segments and freeze the object."""
        unknown = sorted(set(options) - set(self.OPTIONS))
        if unknown:
            raise ProfileError(self.name, unknown[0], f'is unknown (options: '
                               f'{", ".join(self.OPTIONS)})')
        given = {k: v for k, v in options.items() if v is not None}
        values = dict(self.defaults(params, given))
        values.update(given)
        for key, (unit, _desc, lo, hi, integer) in self.OPTIONS.items():
            values[key] = self._check(key, values[key], unit, lo, hi, integer)
        object.__setattr__(self, 'params', params)
        object.__setattr__(self, 'options', dict(values))
        segments = tuple(self.build(params, values))
        object.__setattr__(self, 'segments', segments)
        object.__setattr__(self, '_t0', tuple(s.t0 for s in segments))
        object.__setattr__(self, '_arrays', tuple(np.array([getattr(s, f) for s in segments])
                                                  for f in ('t0', 't1', 'v0', 'v1')))
        object.__setattr__(self, '_frozen', True)

    def __setattr__(self, key, value):
        """Refuse changes: a profile is immutable."""
        raise AttributeError(f'{type(self).__name__} is immutable')

    def _check(self, key, value, unit, lo, hi, integer):
        """Return ``value`` coerced and checked against [lo, hi]; raise ProfileError."""
        try:
            number = float(value)
        except (TypeError, ValueError):
            raise ProfileError(self.name, key, f'= {value!r}: not a number') from None
        if integer:
            if number != int(number):
                raise ProfileError(self.name, key, f'= {value!r}: must be a whole number')
            number = int(number)
        if not (math.isfinite(number) and lo <= number <= hi):
            raise ProfileError(self.name, key, f'= {value!r} {unit}: must lie in '
                               f'[{lo:g}, {hi:g}] {unit}')
        return number

    def fail(self, key, message):
        """Raise ProfileError for option ``key``, its value and ``message``."""
        unit = self.OPTIONS[key][0]
        raise ProfileError(self.name, key, f'= {self.options[key]!r} {unit}: {message}')

    # The subclasses define these -----------------------------------------------------
    def defaults(self, params, given):
        """Return the default options derived from ``params`` and the ``given`` ones (a dict)."""
        raise NotImplementedError

    def build(self, params, o):
        """Return the segments for the checked options ``o``."""
        raise NotImplementedError

    # Timing and values --------------------------------------------------------------
    @property
    def topic(self):
        """Return the node's command topic of the profile."""
        return KIND_TOPICS[self.kind]

    @property
    def unit(self):
        """Return the unit of the command values."""
        return UNITS[self.kind]

    @property
    def duration(self):
        """Return the duration of the profile [s]."""
        return self.segments[-1].t1

    def values(self, t):
        """
        Return the command values at the times ``t`` (numpy array of float).

        Parameters
        ----------
        t : array_like of float
            Times [s] from the start of the profile; before 0 the first value,
            after the end the last one holds.

        """
        t = np.asarray(t, dtype=float)
        t0, t1, v0, v1 = self._arrays
        i = np.clip(np.searchsorted(t0, t, side='right') - 1, 0, len(t0) - 1)
        a, b, x0, x1 = t0[i], t1[i], v0[i], v1[i]
        span = b - a
        frac = np.clip((t - a) / np.where(span > 0.0, span, 1.0), 0.0, 1.0)
        return np.where(span > 0.0, x0 + (x1 - x0) * frac, x1)

    def __call__(self, t):
        """
        Return the command value at the time ``t`` (the scalar form of :meth:`values`).

        Parameters
        ----------
        t : float
            Time [s] from the start of the profile.

        """
        i = min(max(bisect.bisect_right(self._t0, t) - 1, 0), len(self._t0) - 1)
        s = self.segments[i]
        span = s.t1 - s.t0
        if not span > 0.0:
            return float(s.v1)
        frac = min(max((t - s.t0) / span, 0.0), 1.0)
        return float(s.v0 + (s.v1 - s.v0) * frac)

    def segment_at(self, t):
        """
        Return the index of the segment that holds time ``t``.

        Parameters
        ----------
        t : float
            Time [s] from the start of the profile.

        """
        return min(max(bisect.bisect_right(self._t0, t) - 1, 0), len(self._t0) - 1)

    # Interfaces of the command sources ----------------------------------------------
    def controller(self):
        """Return ``fn(t, x=None) -> command``: the value at t [s]; x, the nut [m], unused."""
        return lambda t, x=None: self(t)

    def torque_source(self):
        """Return simulate's torque source ``fn(k, t, x, v) -> torque`` [N m] (torque kind)."""
        if self.kind != 'torque':
            raise ValueError(f'{self.name} commands {self.kind}, not torque')
        ctl = self.controller()

        def fn(k, t, x, v):
            """Return the torque [N m] at tick k, time t [s], nut position x [m]."""
            return ctl(t, x)
        fn.needs_state = bool(getattr(ctl, 'needs_state', False))
        return fn

    def drive_source(self):
        """Return simulate's drive input ``(fn(t) -> (x, v), topic, description)``."""
        nan = float('nan')
        if self.kind == 'velocity':
            fn = (lambda t: (nan, self(t)))
        elif self.kind == 'position':
            fn = (lambda t: (self(t), nan))
        else:
            raise ValueError(f'{self.name} commands torque, not a drive input')
        return fn, self.topic, self.describe()

    def describe(self):
        """Return a one-line description: name and options with units."""
        opts = ' '.join(f'{k}={v:g}' for k, v in self.options.items())
        return f'excite={self.name} {opts}'

    def listing(self):
        """Return the lines of the profile listing of ``excite`` for this profile."""
        lines = [f'{self.name}: {self.summary}',
                 f'  command {self.topic} [{self.unit}], duration {self.duration:.3f} s, '
                 f'{len(self.segments)} segments']
        for key, (unit, desc, lo, hi, _i) in self.OPTIONS.items():
            lines.append(f'  {key} = {self.options[key]:g} {unit}  ({desc}; [{lo:g}, {hi:g}])')
        return lines


def stroke_room(params):
    """Return (lowest, highest) nut position [m] the moves may reach (end stops less margin)."""
    margin = STROKE_MARGIN * (params.stroke_max - params.stroke_min)
    return params.stroke_min + margin, params.stroke_max - margin


def nut_speed_limit(params):
    """Return the nut speed [m/s] of the drive's reference limit (reference_speed_limit)."""
    return params.reference_speed_limit * params.lead / (2.0 * math.pi)


class Builder:
    """
    Append segments one after the other (time runs on from 0).

    Parameters
    ----------
    value : float
        Command value at the start.

    """

    def __init__(self, value):
        """Start at t = 0 with ``value``."""
        self.t, self.value, self.out = 0.0, float(value), []

    def hold(self, duration, label, direction=0, value=None):
        """Hold ``value`` (default: the current one) for ``duration`` [s]."""
        value = self.value if value is None else float(value)
        self.out.append(Segment(self.t, self.t + duration, value, value, label, direction))
        self.t += duration
        self.value = value

    def ramp(self, target, duration, label, direction=0):
        """Ramp linearly to ``target`` in ``duration`` [s]."""
        self.out.append(Segment(self.t, self.t + duration, self.value, float(target), label,
                                direction))
        self.t += duration
        self.value = float(target)

    def move(self, target, speed, label, direction=0):
        """Ramp to ``target`` at ``speed`` (no segment for a zero move)."""
        d = abs(float(target) - self.value)
        if d > 0.0:
            self.ramp(target, d / speed, label, direction)


def check_speed(profile, params, speed):
    """Raise ProfileError if option ``speed`` [m/s] exceeds the nut speed the drive allows."""
    limit = nut_speed_limit(params)
    if speed > limit:
        profile.fail('speed', f'exceeds the nut speed of velocity_limit and max_screw_velocity, '
                     f'{limit:g} m/s')
