"""
Broadband profiles for a frequency response: ``chirp`` and ``multisine`` (no ROS).

Each publishes one command (``command``: torque [N m], nut velocity [m/s] or
nut position [m]) as ``offset + w(t) s(t)``: s(t) a swept sine or a
multisine of :mod:`..freqresp.signals`, w(t) a raised-cosine fade in and
out, with ``settle`` seconds at the offset before and after. The options
default from the axis:

- the band: ``fmax`` twice the drive's loop bandwidth (velocity loop
  K_v / (2 pi J_total) for torque and velocity commands, position loop
  K_p / (2 pi) for position commands), ``fmin`` = fmax / 100;
- the amplitude: a quarter of the limit of the command (``max_torque`` less
  the offset, the nut speed of ``velocity_limit``, a quarter of the stroke
  room), lowered until the motion fits the stroke (less its margins), and
  raised, where the limits allow, to 100 encoder counts of motion at fmax.

A velocity profile ends with a slow move that brings the nut back to where
it started (the sweep's net travel, integrated by Simpson's rule). The limits
are checked on the planned command: the torque within ``max_torque``, the
speed within the nut speed of ``velocity_limit``, the position (and the
travel a velocity profile commands, or a torque profile gives the rigid,
frictionless axis) inside the stroke less its margins.
"""
import math

import numpy as np

from .base import Builder, nut_speed_limit, Profile, ProfileError, Segment, stroke_room
from .breakaway import static_breakaway
from .multisine_design import low_crest_phases, multisine_peak
from ..freqresp import signals

__all__ = ['BROADBAND', 'Chirp', 'COMMANDS', 'Multisine', 'drive_bandwidths']

#: Command codes of option ``command`` (its value is the index).
COMMANDS = ('torque', 'velocity', 'position')
#: Samples per period of fmax of the integrations that check and close the travel.
_SAMPLES = 64
#: Longest grid of those integrations (points).
_MAX_POINTS = 4_000_000
#: Time of each ramp of the return move [s].
_RETURN_RAMP = 0.1


def drive_bandwidths(params):
    """Return (f_v, f_p) [Hz]: velocity loop K_v / (2 pi J_total), position loop K_p / (2 pi)."""
    from ..linear import total_inertia
    f_v = params.velocity_gain / (2.0 * math.pi * total_inertia(params))
    if not f_v > 0.0:
        f_v = 20.0
    f_p = params.position_gain / (2.0 * math.pi)
    return f_v, (f_p if f_p > 0.0 else f_v / 5.0)


def _encoder_step(params):
    """Return the nut travel of one encoder count [m] (0: ideal encoder)."""
    n = params.encoder_counts
    return params.lead / n if n else 0.0


def _window(tau, duration, fade_in, fade_out):
    """Return the raised-cosine fade w(tau) in [0, 1] of a sweep of ``duration`` [s]."""
    w = np.ones_like(tau)
    a = tau < fade_in
    w[a] = 0.5 - 0.5 * np.cos(math.pi * tau[a] / fade_in)
    b = tau > duration - fade_out
    w[b] = 0.5 - 0.5 * np.cos(math.pi * (duration - tau[b]) / fade_out)
    return np.where((tau >= 0.0) & (tau <= duration), w, 0.0)


def _simpson_grid(duration, fmax):
    """Return an odd number of grid points over ``duration`` for Simpson's rule."""
    n = int(min(_MAX_POINTS, max(20001, _SAMPLES * fmax * duration)))
    return n + 1 - n % 2


class _Broadband(Profile):
    """A sweep (:meth:`shape`) faded in and out around an offset, at rest before and after."""

    #: Options of every broadband profile; the unit None is the command's.
    COMMON = {
        'command': ('-', 'command: 0 torque [N m], 1 nut velocity [m/s], 2 nut position [m]',
                    0, 2, True),
        'amplitude': (None, 'peak of the sweep about the offset', 1e-12, 1e5, False),
        'offset': (None, 'command held before, under and after the sweep', -1e5, 1e5, False),
        'fmin': ('Hz', 'lowest frequency of the band', 1e-3, 5e3, False),
        'fmax': ('Hz', 'highest frequency of the band', 1e-3, 5e3, False),
        'settle': ('s', 'rest at the offset before and after the sweep', 0.0, 3600.0, False),
    }
    EXTRA = {}
    kind = 'velocity'
    #: No derived figures (``info --figures``): the frequency response is ``freqresp``'s.
    figures = False

    def __init__(self, params, **options):
        """Take ``command`` (a code or torque/velocity/position), then validate as Profile."""
        command = options.get('command')
        if isinstance(command, str) and command in COMMANDS:
            options['command'] = command = COMMANDS.index(command)
        try:
            kind = COMMANDS[int(command)] if command is not None else 'velocity'
        except (TypeError, ValueError, IndexError):
            kind = 'velocity'                   # the option check names the bad value
        unit = {'torque': 'N m', 'velocity': 'm/s', 'position': 'm'}[kind]
        opts = {k: (unit if u is None else u, d, lo, hi, i)
                for k, (u, d, lo, hi, i) in {**self.COMMON, **self.EXTRA}.items()}
        object.__setattr__(self, 'kind', kind)
        object.__setattr__(self, 'OPTIONS', opts)
        super().__init__(params, **options)

    # The sweep ------------------------------------------------------------------------
    def shape(self, tau, o):
        """Return the sweep s(tau), peak 1 (tau [s] from the start of the sweep)."""
        raise NotImplementedError

    def sweep_time(self, o):
        """Return the duration of the sweep [s] for the options ``o``."""
        raise NotImplementedError

    def fades(self, o):
        """Return the fade-in and fade-out times [s]."""
        raise NotImplementedError

    @property
    def sweep_start(self):
        """Return the start of the sweep [s] from the start of the profile."""
        return self._sweep[0]

    @property
    def sweep_duration(self):
        """Return the duration of the sweep [s], fades included."""
        return self._sweep[1]

    @property
    def command_rate(self):
        """Return the suggested command rate [Hz]: 10 fmax, within [100, 1000] Hz."""
        return max(self.min_command_rate, min(1000.0, max(100.0, 10.0 * self.options['fmax'])))

    @property
    def min_command_rate(self):
        """Return the lowest command rate [Hz] that resolves fmax: 2.5 fmax."""
        return 2.5 * self.options['fmax']

    def _sweep_values(self, tau, o):
        """Return amplitude w(tau) s(tau), zero outside the sweep."""
        dur = self.sweep_time(o)
        fade_in, fade_out = self.fades(o)
        inside = (tau >= 0.0) & (tau <= dur)
        tc = np.where(inside, tau, 0.0)
        return np.where(inside, o['amplitude'] * _window(tc, dur, fade_in, fade_out) *
                        self.shape(tc, o), 0.0)

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
        return Profile.values(self, t) + self._sweep_values(t - self._sweep[0], self.options)

    def __call__(self, t):
        """
        Return the command value at the time ``t`` (the same arithmetic as :meth:`values`).

        Parameters
        ----------
        t : float
            Time [s] from the start of the profile.

        """
        return float(self.values(np.array([float(t)]))[0])

    # Defaults and limits --------------------------------------------------------------
    def defaults(self, params, given):
        """
        Return the defaults: the band from the drive, the amplitude from the limits.

        Parameters
        ----------
        params : ScrewParams
            The axis.
        given : dict
            The options the user gave, by name (SI units).

        """
        f_v, f_p = drive_bandwidths(params)
        fmax = 2.0 * (f_p if self.kind == 'position' else f_v)
        o = dict(command=COMMANDS.index(self.kind), fmax=fmax, settle=0.5)
        try:
            o.update({k: float(v) for k, v in given.items() if k in ('fmin', 'fmax')})
            o['fmin'] = float(given.get('fmin', o['fmax'] / 100.0))
            o.update(self.extra_defaults(params, given, o))
            o['offset'] = float(given.get('offset', self._rest(params)))
            o.update({k: float(v) for k, v in given.items() if k in o})
            o['amplitude'] = self._default_amplitude(params, o)
        except (TypeError, ValueError, ZeroDivisionError, ProfileError):
            o.setdefault('offset', 0.0)
            o.setdefault('amplitude', 1e-12)
            o.update(self.extra_defaults(params, {}, dict(o, fmin=1.0, fmax=2.0)))
        return {k: o[k] for k in self.OPTIONS if k in o}

    def _check(self, key, value, unit, lo, hi, integer):
        """Check as Profile; ``command`` names its choices."""
        if key == 'command' and value not in (0, 1, 2):
            raise ProfileError(self.name, key, f'= {value!r}: must be torque, velocity or '
                               'position (or 0, 1, 2)')
        return Profile._check(self, key, value, unit, lo, hi, integer)

    def extra_defaults(self, params, given, o):
        """Return the defaults of the subclass's own options."""
        return {}

    def _rest(self, params):
        """Return the default offset: the centre torque, zero speed or the start position."""
        if self.kind == 'position':
            return params.initial_position
        if self.kind == 'velocity':
            return 0.0
        t_pos, t_neg = static_breakaway(params)
        lo, hi = min(t_pos, t_neg), max(t_pos, t_neg)
        return 0.0 if lo < 0.0 < hi else 0.5 * (lo + hi)

    def _default_amplitude(self, params, o):
        """Return a quarter of the command's limit, fitted to the stroke, 100 counts if allowed."""
        step = _encoder_step(params)
        if self.kind == 'torque':
            return self._fit(0.25 * (params.max_torque - abs(o['offset'])), params, o)[0]
        if self.kind == 'velocity':
            a, most = self._fit(0.25 * nut_speed_limit(params), params, o)
            floor = 100.0 * step * 2.0 * math.pi * o['fmax']
            return min(max(a, floor), most, self._speed_cap(params, o))
        lo, hi = stroke_room(params)
        room = min(hi - o['offset'], o['offset'] - lo)
        fastest = nut_speed_limit(params) / self._speed_factor(o)
        a = min(0.25 * room, 0.25 * fastest)
        return min(max(a, 100.0 * step), 0.99 * room, 0.99 * fastest)

    def _speed_cap(self, params, o):
        """Return the largest velocity amplitude [m/s] within the nut speed limit."""
        return 0.99 * (nut_speed_limit(params) - abs(o['offset']))

    def _fit(self, amplitude, params, o):
        """Return (``amplitude`` lowered to travel half the room, the amplitude of 0.99 room)."""
        room = self._room(params)
        travel = self._travel(params, dict(o, amplitude=1.0))[0]
        if not travel > 0.0:
            return amplitude, math.inf
        return min(amplitude, 0.5 * room / travel), 0.99 * room / travel

    def _room(self, params):
        """Return the smaller room [m] on either side of the start position."""
        lo, hi = stroke_room(params)
        x0 = params.initial_position
        return min(hi - x0, x0 - lo)

    def _speed_factor(self, o):
        """Return the peak speed over the amplitude of a position sweep [1/s] (fades included)."""
        fade_in, fade_out = self.fades(o)
        return 2.0 * math.pi * o['fmax'] + 0.5 * math.pi / min(fade_in, fade_out)

    def _travel(self, params, o):
        """
        Return (largest travel from the start [m], net travel [m]) of the sweep.

        Velocity: the integral of the sweep; torque: the rigid, frictionless
        axis under it (J_total, the lead); position: the amplitude, net 0.
        """
        if self.kind == 'position':
            return o['amplitude'], 0.0
        from ..linear import total_inertia
        dur = self.sweep_time(o)
        n = _simpson_grid(dur, o['fmax'])
        tau = np.linspace(0.0, dur, n)
        h = dur / (n - 1)
        s = self._sweep_values(tau, o)
        v = np.concatenate(([0.0], np.cumsum(0.5 * h * (s[1:] + s[:-1]))))
        net = h / 3.0 * (s[0] + s[-1] + 4.0 * s[1:-1:2].sum() + 2.0 * s[2:-1:2].sum())
        if self.kind == 'velocity':
            return float(np.max(np.abs(v))), float(net)
        x = np.concatenate(([0.0], np.cumsum(0.5 * h * (v[1:] + v[:-1]))))
        scale = params.lead / (2.0 * math.pi) / total_inertia(params)
        return float(np.max(np.abs(x)) * scale), float(x[-1] * scale)

    def check(self, params, o):
        """Raise ProfileError for a band or a sweep that leaves the limits or the stroke."""
        if not o['fmin'] < o['fmax']:
            self.fail('fmax', f'must exceed fmin {o["fmin"]:g} Hz')
        a, c = o['amplitude'], o['offset']
        lo, hi = stroke_room(params)
        if self.kind == 'torque' and abs(c) + a > params.max_torque:
            self.fail('amplitude', f'with offset {c:g} N m exceeds max_torque '
                      f'{params.max_torque:g} N m')
        limit = nut_speed_limit(params)
        if self.kind == 'velocity' and abs(c) + a > limit:
            self.fail('amplitude', f'with offset {c:g} m/s exceeds the nut speed of '
                      f'velocity_limit, {limit:g} m/s')
        if self.kind == 'position':
            if not (lo <= c - a and c + a <= hi):
                self.fail('amplitude', f'around offset {c:g} m leaves [{lo:g}, {hi:g}] m (the '
                          'stroke less its margins)')
            speed = a * self._speed_factor(o)
            if speed > limit:
                self.fail('amplitude', f'moves the target at up to {speed:g} m/s, more than '
                          f'the nut speed of velocity_limit, {limit:g} m/s')
            return 0.0
        travel, net = self._travel(params, o)
        drift = abs(c) * self.sweep_time(o) if self.kind == 'velocity' else 0.0
        room = self._room(params)
        if travel + drift > room:
            what = 'commands' if self.kind == 'velocity' else 'moves the rigid, frictionless axis'
            self.fail('amplitude', f'{what} a travel of {travel + drift:g} m, more than the '
                      f'{room:g} m of stroke room; lower amplitude or raise fmin')
        return net + c * self.sweep_time(o) if self.kind == 'velocity' else 0.0

    def build(self, params, o):
        """
        Return the rest, the sweep, the return move (velocity) and the rest.

        Parameters
        ----------
        params : ScrewParams
            The axis.
        o : dict
            Every option of the profile, by name (SI units), defaults filled in.

        """
        net = self.check(params, o)
        b = Builder(o['offset'])
        b.hold(o['settle'], 'rest')
        start, dur = b.t, self.sweep_time(o)
        object.__setattr__(self, '_sweep', (start, dur))
        b.out.append(Segment(start, start + dur, o['offset'], o['offset'], self.label(o), 0))
        b.t += dur
        if self.kind == 'velocity':
            _return_move(b, net, 0.5 * (nut_speed_limit(params) - abs(o['offset'])))
        b.hold(o['settle'], 'rest')
        return b.out

    def label(self, o):
        """Return the label of the sweep segment."""
        return f'{self.name} {o["fmin"]:g}..{o["fmax"]:g} Hz'


def _return_move(b, net, speed_room):
    """Append a trapezoid (or triangle) of speed whose travel undoes ``net`` [m]."""
    if net == 0.0 or speed_room <= 0.0:
        return
    base = b.value
    r = _RETURN_RAMP
    speed = min(0.25 * speed_room, abs(net) / r)     # a triangle for a short move
    hold = abs(net) / speed - r
    peak = base - math.copysign(speed, net)
    b.ramp(peak, r, 'return', int(-math.copysign(1.0, net)))
    if hold > 0.0:
        b.hold(hold, 'return', int(-math.copysign(1.0, net)))
    b.ramp(base, r, 'return', int(-math.copysign(1.0, net)))


class Chirp(_Broadband):
    """
    A swept sine, logarithmic (equal time per decade) or linear, from fmin to fmax.

    The instantaneous frequency is f(tau) = fmin (fmax / fmin)^(tau / T) (log)
    or fmin + (fmax - fmin) tau / T (linear) at tau [s] into the sweep of
    ``duration`` T; it fades in over one period of fmin and out over ten
    periods of fmax (each at most a tenth of T).
    """

    name = 'chirp'
    summary = 'swept sine (chirp) from fmin to fmax (frequency response)'
    EXTRA = {
        'duration': ('s', 'time of the sweep, fades included', 0.01, 36000.0, False),
        'log': ('-', '1: logarithmic sweep (equal time per decade), 0: linear', 0, 1, True),
    }

    def extra_defaults(self, params, given, o):
        """Return the default duration: 10 periods of fmin, at least 2 s; log sweep."""
        return dict(duration=max(2.0, 10.0 / float(o['fmin'])), log=1)

    def sweep_time(self, o):
        """Return the sweep's duration [s]."""
        return o['duration']

    def fades(self, o):
        """Return (one period of fmin, ten of fmax), each at most a tenth of the sweep [s]."""
        tenth = 0.1 * o['duration']
        return min(1.0 / o['fmin'], tenth), min(10.0 / o['fmax'], tenth)

    def shape(self, tau, o):
        """Return sin(phi(tau)) of :func:`..freqresp.signals.chirp`."""
        return signals.chirp(tau, o['fmin'], o['fmax'], o['duration'],
                             sweep='log' if o['log'] else 'linear')

    def frequency(self, t):
        """Return the instantaneous frequency [Hz] at profile times ``t`` [s] (NaN outside)."""
        o = self.options
        tau = np.asarray(t, dtype=float) - self.sweep_start
        f = signals.chirp_frequency(tau, o['fmin'], o['fmax'], o['duration'],
                                    sweep='log' if o['log'] else 'linear')
        return np.where((tau >= 0.0) & (tau <= o['duration']), f, np.nan)


class Multisine(_Broadband):
    """
    A sum of sines of equal amplitude on the lines k / period in [fmin, fmax], low crest factor.

    ``lines`` log-spaced lines (merged where they round to one harmonic of
    1 / ``period``), phases of a low crest factor (:meth:`design`), scaled so
    the signal's peak is ``amplitude``. One period fades in, ``periods`` whole periods run
    at full amplitude (the measurement), one period fades out.
    """

    name = 'multisine'
    summary = 'multisine of low crest factor on lines from fmin to fmax (frequency response)'
    EXTRA = {
        'period': ('s', 'period of the signal (its line spacing is 1 / period)', 1e-3, 3600.0,
                   False),
        'periods': ('-', 'whole periods at full amplitude', 1, 10000, True),
        'lines': ('-', 'log-spaced lines wanted (merged on the 1 / period grid)', 1, 100000,
                  True),
    }

    def extra_defaults(self, params, given, o):
        """Return the defaults: period 1 / fmin, 4 periods, 50 lines."""
        return dict(period=1.0 / float(o['fmin']), periods=4, lines=50)

    def check(self, params, o):
        """Raise ProfileError for a period shorter than 1 / fmin, then as every profile."""
        if o['fmin'] < o['fmax']:
            self.frequencies(o)
        return super().check(params, o)

    def sweep_time(self, o):
        """Return the duration [s]: the fade periods and the full ones."""
        return (o['periods'] + 2) * o['period']

    def fades(self, o):
        """Return one period for each fade [s]."""
        return o['period'], o['period']

    def frequencies(self, o=None):
        """Return the line frequencies [Hz]."""
        o = self.options if o is None else o
        if o['fmin'] * o['period'] < 1.0 - 1e-9:
            raise ProfileError(self.name, 'period', f'= {o["period"]!r} s: is shorter than '
                               f'1 / fmin = {1.0 / o["fmin"]:g} s (the lowest line must '
                               'complete a period)')
        f = signals.multisine_frequencies(o['fmin'], o['fmax'], o['period'], o['lines'])
        if not len(f):
            raise ProfileError(self.name, 'lines', f'= {o["lines"]!r}: no line in the band')
        return f

    def design(self, o=None):
        """
        Return (line frequencies [Hz], phases [rad], gain) of the multisine, peak 1.

        Phases of a low crest factor and the gain that makes the peak 1:
        :mod:`.multisine_design`.
        """
        o = self.options if o is None else o
        key = (o['fmin'], o['fmax'], o['period'], o['lines'])
        cache = self.__dict__.get('_design')
        if cache and cache[0] == key:
            return cache[1]
        f = self.frequencies(o)
        ph = low_crest_phases(f, o['period'])
        peak = multisine_peak(f, ph, o['period'])
        out = (f, ph, 1.0 / peak)
        object.__setattr__(self, '_design', (key, out))
        return out

    def shape(self, tau, o):
        """Return the multisine with peak 1 (:meth:`design`)."""
        f, ph, gain = self.design(o)
        return gain * signals.multisine(tau, f, 1.0, ph)


#: The broadband profiles by name.
BROADBAND = {cls.name: cls for cls in (Chirp, Multisine)}
