"""
Standard identification profiles of the axis: commands as functions of time (no ROS).

Four profiles, each an immutable object with a name, the command it uses, a
duration and its command values (``values(t)`` on numpy arrays, ``profile(t)``
on one time):

- ``breakaway``: a slow motor torque ramp [N m] from the centre torque past
  breakaway toward +theta and back, then toward -theta and back
  (``torque_command``);
- ``sweep``: a ladder of constant nut speeds [m/s], log-spaced from well below
  the Stribeck velocity to fast, in both directions, with the same travel back
  (``velocity_command``);
- ``reversals``: small back-and-forth moves of the nut position [m] with dwells,
  so the backlash shows (``position_command``);
- ``iso230``: bidirectional positioning in the style of ISO 230-2, linear test
  cycle: targets spread over a travel, each approached from below and from
  above with an overshoot, a dwell at each target, several cycles
  (``position_command``).

Every profile is a piecewise-linear sequence of :class:`Segment` s; the
options have units, defaults derived from the axis parameters (stroke, torque
and velocity limits, lead) and ranges, and a value outside them raises
:class:`ProfileError` naming the profile, the option, the value and what is
allowed. ``make_profile(name, params, **options)`` builds one; ``PROFILES``
maps the names to the classes. The command sense is the node's: torque in
the theta sense, nut velocity and position along +x.
"""
import math

from .base import (Builder, check_speed, nut_speed_limit, stroke_room, Profile,
                   ProfileError, Segment, STROKE_MARGIN)
from .resolution import RESOLVE, stribeck_notes, velocity_quantum

__all__ = ['ALL_PROFILES', 'PROFILES', 'ProfileError', 'Segment', 'make_profile', 'BreakawayRamp',
           'SpeedSweep', 'Reversals', 'Iso230', 'static_breakaway']

_GOLDEN = (math.sqrt(5.0) - 1.0) / 2.0


def static_breakaway(params, mu=None):
    """
    Return (T_up, T_down): the edges [N m] of the static band of motor torque (theta sense).

    Raising the torque above T_up starts the screw toward +theta, lowering
    it below T_down toward -theta; between them the axis stands still. The
    quasi-static closed form of the rigid axis (doc/model.md sections 7-8):
    the thread torque to drive against or with the axial load (gravity and
    the external force, plus the guide's Coulomb force against the motion),
    plus the bearing's Coulomb torque and the collar friction. A torque
    moving the nut toward +x has the sign of the hand sign.

    Parameters
    ----------
    params : ScrewParams
        The axis.
    mu : float, optional
        Thread friction coefficient (default ``mu_s``, the static one); the
        apparent coefficient is ``mu`` times the thread factor.

    """
    from ...core import geometry
    p = params
    mu_app = (p.mu_s if mu is None else mu) * p.thread_factor
    lam, r = p.lead_angle, p.r_m
    load = p.moving_mass * p.gravity * math.sin(p.inclination) - p.external_force
    out = []
    for s in (1.0, -1.0):                      # motion toward +x, toward -x
        w = s * load + p.guide_coulomb         # the load opposing this motion [N]
        if w >= 0.0:
            thread = geometry.raise_torque(w, r, mu_app, lam)
        else:
            thread = geometry.lower_torque(-w, r, mu_app, lam)
        rest = p.bearing_coulomb + p.collar_mu * p.collar_radius * abs(w)
        out.append(p.hand_sign * s * (thread + rest))
    plus_x, minus_x = out
    return (plus_x, minus_x) if p.hand_sign > 0 else (minus_x, plus_x)


class BreakawayRamp(Profile):
    """
    Slow motor torque ramps from the centre torque past breakaway, each direction in turn.

    Dwell at the centre, ramp toward +theta to centre + peak and back, dwell,
    the same toward -theta, dwell. The ramps are quasi-static: the default
    rate, peak / ramp_time, changes the torque by less than 0.1 % of the peak
    within the axis' slowest mechanical period (a few ms). Under
    :meth:`controller` a ramp ends once the nut has moved ``abort_travel``
    from where the ramp began: the torque returns to the centre and holds
    until the direction's ramp time is over, so a torque-driven axis does
    not run away after breakaway. :meth:`values` gives the planned ramps.
    """

    name = 'breakaway'
    kind = 'torque'
    summary = 'motor torque ramps past breakaway toward +theta, then -theta'
    OPTIONS = {
        'center': ('N m', 'torque of the dwells and the start of the ramps', -1e5, 1e5, False),
        'peak': ('N m', 'ramp amplitude from the centre', 1e-9, 1e5, False),
        'ramp_time': ('s', 'time of each ramp from the centre to the peak', 0.01, 3600.0,
                      False),
        'dwell': ('s', 'dwell at the centre before, between and after the ramps', 0.0,
                  3600.0, False),
        'abort_travel': ('m', 'nut travel that ends a ramp (controller)', 1e-9, 1.0, False),
    }

    def defaults(self, params, given):
        """
        Return the defaults: centre in the static band, peak 1.5 x nominal breakaway.

        Parameters
        ----------
        params : ScrewParams
            The axis.
        given : dict
            The options the user gave, by name (SI units).

        """
        t_pos, t_neg = static_breakaway(params)
        lo, hi = min(t_pos, t_neg), max(t_pos, t_neg)
        center = 0.0 if lo < 0.0 < hi else 0.5 * (lo + hi)
        center = float(given.get('center', center))
        reach = max(abs(t_pos - center), abs(t_neg - center))
        room = params.max_torque - abs(center)
        peak = min(0.95 * room, max(1.5 * reach, 0.05 * params.max_torque))
        return dict(center=center, peak=peak, ramp_time=2.0, dwell=0.5,
                    abort_travel=2e-4)

    def build(self, params, o):
        """
        Return the dwells and ramps.

        Parameters
        ----------
        params : ScrewParams
            The axis.
        o : dict
            Every option of the profile, by name (SI units), defaults filled in.

        """
        if abs(o['center']) + o['peak'] > params.max_torque:
            self.fail('peak', f'with centre {o["center"]:g} N m exceeds max_torque '
                      f'{params.max_torque:g} N m (the motor would clip the ramp)')
        c, a, tr, d = o['center'], o['peak'], o['ramp_time'], o['dwell']
        b = Builder(c)
        b.hold(d, 'dwell')
        for s, sign in ((1, '+'), (-1, '-')):
            b.ramp(c + s * a, tr, f'ramp {sign}theta up', s)
            b.ramp(c, tr, f'ramp {sign}theta down', s)
            b.hold(d, 'dwell')
        return b.out

    def controller(self):
        """Return ``fn(t, x=None)``: the ramps, each ending at abort_travel of nut motion."""
        return _AbortingRamp(self)


class _AbortingRamp:
    """The torque of a breakaway profile that returns to the centre once the nut moved."""

    needs_state = True

    def __init__(self, profile):
        self.profile = profile
        self.travel = profile.options['abort_travel']
        self.center = profile.options['center']
        self.start = {}          # direction -> nut position at the start of its ramps
        self.aborted = set()

    def __call__(self, t, x=None):
        p = self.profile
        s = p.segments[p.segment_at(t)]
        if s.direction == 0 or x is None or not t < p.duration:
            return p(t)
        x0 = self.start.setdefault(s.direction, x)
        if abs(x - x0) > self.travel:
            self.aborted.add(s.direction)
        return self.center if s.direction in self.aborted else p(t)


class SpeedSweep(Profile):
    """
    A ladder of constant nut speeds, log-spaced, each held to settle and measure, both ways.

    The first direction (toward the side with more room) runs from the fastest
    level down to the slowest, then the other direction likewise: the axis
    breaks away and reverses at speed, and reaches the slow levels while
    already sliding (a velocity loop starting from rest at a slow speed would
    first wind its integral up for seconds). Both directions hold the same
    levels for the same times, so the nut returns to where it started.
    ``v_min`` defaults to a nut speed whose thread sliding speed
    v / sin(lambda) is a quarter of the Stribeck velocity.

    With a quantised encoder (:mod:`.resolution`) ``v_min`` is at least
    RESOLVE velocity quanta and each level starts from a ``rest``: each
    breaks away (mu_s) and passes the Stribeck range (:meth:`notes`).
    """

    name = 'sweep'
    kind = 'velocity'
    summary = 'stepped constant nut speeds (Stribeck curve), both directions'
    OPTIONS = {
        'v_min': ('m/s', 'slowest nut speed', 1e-9, 1e3, False),
        'v_max': ('m/s', 'fastest nut speed', 1e-9, 1e3, False),
        'levels': ('-', 'number of speeds, log-spaced', 1, 100, True),
        'settle': ('s', 'start of each level left to settle', 0.0, 3600.0, False),
        'measure': ('s', 'rest of each level (the measurement window)', 0.01, 3600.0, False),
        'first': ('-', 'first direction: +1 toward +x, -1 toward -x', -1, 1, True),
        'stop': ('s', 'zero speed at the end', 0.0, 3600.0, False),
        'rest': ('s', 'standstill before each level (a breakaway each)', 0.0, 3600.0, False),
    }

    def defaults(self, params, given):
        """
        Return the defaults: v_min below the Stribeck velocity, v_max within stroke.

        Parameters
        ----------
        params : ScrewParams
            The axis.
        given : dict
            The options the user gave, by name (SI units).

        """
        v_min = max(1e-6, 0.25 * params.stribeck_velocity * math.sin(params.lead_angle),
                    RESOLVE * velocity_quantum(params))
        lo, hi = stroke_room(params)
        x0 = params.initial_position
        first = 1 if hi - x0 >= x0 - lo else -1
        o = dict(v_min=v_min, levels=8, settle=0.3, measure=0.7, first=first, stop=0.3,
                 rest=0.2 if params.encoder_counts else 0.0)
        try:                    # v_max to fit the options given (checked later)
            o.update({k: float(v) for k, v in given.items() if k in o})
            o['levels'] = max(1, int(o['levels']))
            room = 0.9 * (hi - x0 if o['first'] > 0 else x0 - lo)
        except (TypeError, ValueError):
            o['v_max'] = 0.0
            return o
        v_max = 0.5 * nut_speed_limit(params)
        while v_max > o['v_min'] and self._travel(dict(o, v_max=v_max)) > room:
            v_max *= 0.95
        o['v_max'] = max(v_max, o['v_min'])
        return o

    @staticmethod
    def speeds(o):
        """Return the levels [m/s], slowest first, for the options ``o``."""
        n = o['levels']
        if n == 1:
            return [o['v_min']]
        ratio = o['v_max'] / o['v_min']
        return [o['v_min'] * ratio ** (i / (n - 1)) for i in range(n)]

    def _travel(self, o):
        """Return the nut travel [m] of one direction."""
        return sum(v * (o['settle'] + o['measure']) for v in self.speeds(o))

    def build(self, params, o):
        """
        Return the levels of both directions, fastest first, and the stop.

        Parameters
        ----------
        params : ScrewParams
            The axis.
        o : dict
            Every option of the profile, by name (SI units), defaults filled in.

        """
        if o['first'] == 0:
            self.fail('first', 'must be +1 or -1')
        if o['v_max'] < o['v_min']:
            self.fail('v_max', f'is below v_min {o["v_min"]:g} m/s')
        limit = nut_speed_limit(params)
        if o['v_max'] > limit:
            self.fail('v_max', f'exceeds the nut speed of velocity_limit, {limit:g} m/s')
        lo, hi = stroke_room(params)
        x0 = params.initial_position
        room = hi - x0 if o['first'] > 0 else x0 - lo
        travel = self._travel(o)
        if travel > room:
            self.fail('v_max', f'makes a travel of {travel:g} m, more than the {room:g} m '
                      f'of stroke left (less {STROKE_MARGIN:.0%} margins); lower v_max, '
                      'settle or measure')
        b = Builder(0.0)
        for s in (o['first'], -o['first']):
            for v in reversed(self.speeds(o)):
                if o['rest'] > 0.0:
                    b.hold(o['rest'], 'rest', s, 0.0)
                b.hold(o['settle'] + o['measure'], f'level {s * v:+.4g} m/s', s, s * v)
        b.hold(o['stop'], 'stop', 0, 0.0)
        return b.out

    def notes(self):
        """Return what the axis's encoder cannot resolve with this sweep (lines, maybe none)."""
        return stribeck_notes(self.params)

    def listing(self):
        """Return the lines of ``excite --list``, with the :meth:`notes`."""
        return super().listing() + ['  ' + n for n in self.notes()]

    def describe(self):
        """Return the one-line description, with the :meth:`notes`."""
        return '; '.join([super().describe()] + self.notes())


class Reversals(Profile):
    """
    Small back-and-forth moves of the nut with a dwell after each, so the backlash shows.

    Each cycle: from the centre to centre + amplitude, dwell, back to the
    centre, dwell, to centre - amplitude, dwell, back to the centre, dwell;
    ``cycles`` times. The centre is reached from above and from below in
    every cycle, so :func:`.figures.reversal_error` measures the lost motion
    there. Each move is a ramp of the position target at ``speed``. On a
    loaded vertical axis the nut stays on the flank the load presses; the
    backlash shows on a horizontal axis or with a changing external force.
    """

    name = 'reversals'
    kind = 'position'
    summary = 'small back-and-forth nut moves with dwells (backlash)'
    OPTIONS = {
        'center': ('m', 'middle of the moves', -100.0, 100.0, False),
        'amplitude': ('m', 'move from the centre to each side', 1e-9, 10.0, False),
        'cycles': ('-', 'number of back-and-forth cycles', 1, 1000, True),
        'dwell': ('s', 'dwell after each move', 0.0, 3600.0, False),
        'speed': ('m/s', 'speed of the position target during a move', 1e-9, 1e3, False),
    }

    def defaults(self, params, given):
        """
        Return the defaults: 3 backlashes (at least 0.2 mm) around the initial position.

        Parameters
        ----------
        params : ScrewParams
            The axis.
        given : dict
            The options the user gave, by name (SI units).

        """
        return dict(center=params.initial_position, amplitude=max(3.0 * params.backlash, 2e-4),
                    cycles=5, dwell=0.5, speed=min(2e-3, 0.2 * nut_speed_limit(params)))

    def build(self, params, o):
        """
        Return the moves and dwells.

        Parameters
        ----------
        params : ScrewParams
            The axis.
        o : dict
            Every option of the profile, by name (SI units), defaults filled in.

        """
        check_speed(self, params, o['speed'])
        lo, hi = stroke_room(params)
        c, a = o['center'], o['amplitude']
        if not (lo <= c - a and c + a <= hi):
            self.fail('amplitude', f'around centre {c:g} m leaves [{lo:g}, {hi:g}] m (the '
                      f'stroke less {STROKE_MARGIN:.0%} margins)')
        b = Builder(params.initial_position)
        b.move(c, o['speed'], 'to centre')
        for _k in range(o['cycles']):
            for s in (1, -1):
                sign = '+' if s > 0 else '-'
                b.move(c + s * a, o['speed'], f'move {sign}', s)
                b.hold(o['dwell'], f'dwell {sign}', s)
                b.move(c, o['speed'], f'back from {sign}', -s)
                b.hold(o['dwell'], f'dwell centre from {sign}', -s)
        return b.out


class Iso230(Profile):
    """
    Bidirectional positioning in the style of ISO 230-2, linear test cycle.

    ``targets`` positions P_1 < ... < P_m spread over ``travel`` around
    ``center``, the interior ones offset irregularly by up to a tenth of the
    spacing (fractional parts of i times the golden ratio), so that periodic
    errors of the lead are not sampled in phase. Each cycle approaches every
    target from below (ascending pass, from P_1 - overshoot), passes P_m by
    ``overshoot``, and approaches every target from above (descending pass)
    down to P_1 - overshoot; a dwell at each target gives the measurement.
    ISO 230-2 asks for 5 cycles (the default) and at least 5 targets per
    metre and 5 in all. Moves are ramps of the position target at ``speed``.
    """

    name = 'iso230'
    kind = 'position'
    summary = 'ISO 230-2 bidirectional positioning, linear cycle (reversal error)'
    OPTIONS = {
        'center': ('m', 'middle of the targets', -100.0, 100.0, False),
        'travel': ('m', 'distance from the first to the last target', 1e-9, 200.0, False),
        'targets': ('-', 'number of target positions', 2, 1000, True),
        'cycles': ('-', 'bidirectional cycles', 1, 1000, True),
        'overshoot': ('m', 'distance passed beyond the end targets before reversing',
                      0.0, 10.0, False),
        'dwell': ('s', 'dwell at each target', 0.0, 3600.0, False),
        'speed': ('m/s', 'speed of the position target during a move', 1e-9, 1e3, False),
    }

    def defaults(self, params, given):
        """
        Return the defaults: 5 targets over half the stroke, 5 cycles.

        Parameters
        ----------
        params : ScrewParams
            The axis.
        given : dict
            The options the user gave, by name (SI units).

        """
        lo, hi = stroke_room(params)
        overshoot = max(5.0 * params.backlash, 5e-4)
        return dict(center=0.5 * (lo + hi), travel=0.5 * (hi - lo - 2.0 * overshoot),
                    targets=5, cycles=5, overshoot=overshoot, dwell=1.0,
                    speed=min(0.02, 0.25 * nut_speed_limit(params)))

    def target_positions(self):
        """Return the target positions P_1 .. P_m [m], ascending."""
        return self._positions(self.options)

    @staticmethod
    def _positions(o):
        m = o['targets']
        step = o['travel'] / (m - 1)
        start = o['center'] - 0.5 * o['travel']
        out = []
        for i in range(m):
            offset = 0.0 if i in (0, m - 1) else 0.1 * step * (2.0 * ((i * _GOLDEN) % 1.0) - 1.0)
            out.append(start + i * step + offset)
        return out

    def build(self, params, o):
        """
        Return the ascending and descending passes of every cycle.

        Parameters
        ----------
        params : ScrewParams
            The axis.
        o : dict
            Every option of the profile, by name (SI units), defaults filled in.

        """
        check_speed(self, params, o['speed'])
        lo, hi = stroke_room(params)
        pos = self._positions(o)
        if pos[0] - o['overshoot'] < lo or pos[-1] + o['overshoot'] > hi:
            self.fail('travel', f'with overshoot {o["overshoot"]:g} m around centre '
                      f'{o["center"]:g} m leaves [{lo:g}, {hi:g}] m (the stroke less '
                      f'{STROKE_MARGIN:.0%} margins)')
        v = o['speed']
        b = Builder(params.initial_position)
        b.move(pos[0] - o['overshoot'], v, 'to start')
        for k in range(o['cycles']):
            for i, p in enumerate(pos):
                b.move(p, v, f'cycle {k + 1} up to P{i + 1}', 1)
                b.hold(o['dwell'], f'cycle {k + 1} P{i + 1} up', 1)
            b.move(pos[-1] + o['overshoot'], v, 'overshoot', 1)
            for i in range(len(pos) - 1, -1, -1):
                b.move(pos[i], v, f'cycle {k + 1} down to P{i + 1}', -1)
                b.hold(o['dwell'], f'cycle {k + 1} P{i + 1} down', -1)
            b.move(pos[0] - o['overshoot'], v, 'overshoot', -1)
        b.move(params.initial_position, v, 'back')
        b.hold(min(o['dwell'], 0.5), 'end')
        return b.out


#: Profile name -> class.
PROFILES = {cls.name: cls for cls in (BreakawayRamp, SpeedSweep, Reversals, Iso230)}

from .broadband import BROADBAND  # noqa: E402 (it imports static_breakaway from here)
PROFILES.update(BROADBAND)
from .commission import COMMISSION  # noqa: E402 (it builds the profiles above)
#: Every name ``make_profile`` builds: the single profiles and the chained commission run
#: (not a single profile: a part per command kind).
ALL_PROFILES = dict(PROFILES, **COMMISSION)


def make_profile(name, params, **options):
    """
    Return the profile ``name`` for the axis ``params`` with ``options``.

    Parameters
    ----------
    name : str
        A key of :data:`ALL_PROFILES` (a single profile, or ``commission``).
    params : ScrewParams
        The axis (stroke, limits, lead, initial position).
    **options
        Options of the profile (SI units); None keeps the default.

    """
    try:
        cls = ALL_PROFILES[name]
    except KeyError:
        raise ProfileError(name, 'name', '', f'unknown excitation profile {name!r} (profiles: '
                           f'{", ".join(ALL_PROFILES)})') from None
    return cls(params, **options)
