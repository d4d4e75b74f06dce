"""
The position profiles: ``reversals``, ``iso230`` and ``warmup``, nut position targets [m] (no ROS).

- ``reversals``: small back-and-forth moves with dwells, so the backlash shows;
- ``iso230``: bidirectional positioning in the style of ISO 230-2, linear
  test cycle: targets spread over a travel, each approached from below and
  from above with an overshoot, a dwell at each target, several cycles;
- ``warmup``: the thermal drift test of ISO 230-3: back-and-forth moves over
  a stroke that heat the screw, with measurement stops at both ends of it at
  regular intervals.

All command ``position_command`` (nut position along +x).
"""
import math

from .base import Builder, check_speed, nut_speed_limit, Profile, STROKE_MARGIN, stroke_room

_GOLDEN = (math.sqrt(5.0) - 1.0) / 2.0


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


class Warmup(Profile):
    """
    The warm-up drift test of ISO 230-3: moves that heat the screw, with measurement stops.

    The nut runs back and forth over ``stroke`` around ``center`` at
    ``speed`` for ``interval`` seconds, then stops at the lower and at the
    upper end of the stroke for ``dwell`` each (segments ``stop K low`` and
    ``stop K high``), each approached from below so the backlash does not
    enter; ``stops`` times, after a first stop pair before any heating. The
    drift is where the nut stands at a stop against where it was told to:
    ``leadscrew_sim plot`` shows it against time beside the screw's
    temperature. A run of ``warmup`` heats the screw only with
    ``screw_heat_capacity`` > 0 (and ``ageing_speedup`` turns hours into
    minutes).
    """

    name = 'warmup'
    kind = 'position'
    figures = False             # its figure is the drift at the stops: leadscrew_sim plot
    summary = 'ISO 230-3 warm-up: back-and-forth moves with measurement stops (thermal drift)'
    OPTIONS = {
        'center': ('m', 'middle of the stroke', -100.0, 100.0, False),
        'stroke': ('m', 'length of the back-and-forth moves', 1e-6, 200.0, False),
        'speed': ('m/s', 'speed of the position target during a move', 1e-9, 1e3, False),
        'interval': ('s', 'time of back-and-forth moves between two stop pairs', 1e-3, 1e6,
                     False),
        'stops': ('-', 'stop pairs after the first', 1, 10000, True),
        'dwell': ('s', 'time at each stop', 1e-3, 3600.0, False),
    }

    def defaults(self, params, given):
        """
        Return the defaults: half the stroke, 10 stop pairs 10 s apart.

        Parameters
        ----------
        params : ScrewParams
            The axis.
        given : dict
            The options the user gave, by name (SI units).

        """
        lo, hi = stroke_room(params)
        return dict(center=0.5 * (lo + hi), stroke=0.5 * (hi - lo),
                    speed=min(0.05, 0.5 * nut_speed_limit(params)), interval=10.0, stops=10,
                    dwell=1.0)

    def stop_positions(self):
        """Return the (low, high) measurement positions [m]."""
        o = self.options
        return o['center'] - 0.5 * o['stroke'], o['center'] + 0.5 * o['stroke']

    def build(self, params, o):
        """
        Return the moves and the measurement stops.

        Parameters
        ----------
        params : ScrewParams
            The axis.
        o : dict
            Every option of the profile, by name (SI units), defaults filled in.

        """
        check_speed(self, params, o['speed'])
        lo, hi = stroke_room(params)
        low, high = o['center'] - 0.5 * o['stroke'], o['center'] + 0.5 * o['stroke']
        if not (lo <= low - o['stroke'] * 0.05 and high <= hi):
            self.fail('stroke', f'around centre {o["center"]:g} m leaves [{lo:g}, {hi:g}] m '
                      f'(the stroke less {STROKE_MARGIN:.0%} margins, and a 5 % run-up)')
        v = o['speed']
        run_up = low - 0.05 * o['stroke']
        b = Builder(params.initial_position)
        b.move(run_up, v, 'to start')

        def stop_pair(k):
            b.move(low, v, f'to stop {k} low', 1)
            b.hold(o['dwell'], f'stop {k} low', 1)
            b.move(high, v, f'to stop {k} high', 1)
            b.hold(o['dwell'], f'stop {k} high', 1)

        stop_pair(0)
        for k in range(1, o['stops'] + 1):
            end = b.t + o['interval']
            b.move(run_up, v, f'warm-up {k}', -1)     # from the high stop, down
            while b.t < end:
                b.move(high, v, f'warm-up {k}', 1)
                b.move(run_up, v, f'warm-up {k}', -1)
            stop_pair(k)                              # from below, as the first pair
        b.move(params.initial_position, v, 'back')
        return b.out
