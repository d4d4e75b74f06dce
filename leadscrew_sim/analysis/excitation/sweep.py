"""
The ``sweep`` profile: a ladder of constant nut speeds [m/s] in both directions (no ROS).

Log-spaced from well below the Stribeck velocity to fast, with the same
travel back (``velocity_command``, nut velocity along +x).
"""
import math

from .base import Builder, nut_speed_limit, Profile, STROKE_MARGIN, stroke_room
from .resolution import RESOLVE, stribeck_notes, velocity_quantum


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
        """Return the lines of the profile listing of ``excite``, with the :meth:`notes`."""
        return super().listing() + ['  ' + n for n in self.notes()]

    def describe(self):
        """Return the one-line description, with the :meth:`notes`."""
        return '; '.join([super().describe()] + self.notes())
