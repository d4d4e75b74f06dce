"""
The broadband profiles ``chirp`` and ``multisine``: frequency, lines, crest factor, limits.

The oracles are closed forms written here: the zero crossings of a
logarithmic and a linear sweep (phi(t_k) = k pi solved for t_k), the line
set of the documented rule (log-spaced, rounded to the harmonics of
1 / period), the RMS of n equal lines (a sqrt(n / 2)), the in-phase crest
factor sqrt(2 n), the drive's loop bandwidths from the parameters
(K_v / (2 pi J_total), K_p / (2 pi)), the axis limits, and the travel bound
of a swept velocity, 2 A / (pi fmin).
"""
import math

from helpers import cli
from leadscrew_sim import load_preset
from leadscrew_sim.analysis.excitation import profiles as E
from leadscrew_sim.core.params import ScrewParams
import numpy as np
import pytest

from test_excitation import assert_one_clear_error   # noqa: I100

PRESETS = ('tr12x3', 'tr8x8', 'stick_slip', 'seed_a')
COMMANDS = ('torque', 'velocity', 'position')


def nut_speed_limit(p):
    """Return the nut speed [m/s] of the motor velocity limit: omega_max l / (2 pi)."""
    return p.velocity_limit * p.pitch * p.starts / (2.0 * math.pi)


def room(p):
    """Return (lowest, highest) nut position [m]: the stroke less 2 % margins."""
    m = 0.02 * (p.stroke_max - p.stroke_min)
    return p.stroke_min + m, p.stroke_max - m


def crossings(prof, t0, t1, dt=2e-6):
    """Return the times [s] where the profile crosses its offset, by linear interpolation."""
    t = np.arange(t0, t1, dt)
    v = prof.values(t) - prof.options['offset']
    i = np.flatnonzero((v[:-1] < 0) != (v[1:] < 0))
    return t[i] - v[i] * dt / (v[i + 1] - v[i])


@pytest.mark.parametrize('log', [1, 0])
def test_the_chirp_crosses_zero_where_its_closed_form_phase_is_k_pi(log):
    f0, f1, dur = 5.0, 80.0, 2.0
    prof = E.make_profile('chirp', load_preset('tr12x3'), fmin=f0, fmax=f1, duration=dur,
                          log=log, settle=0.3)
    s = prof.sweep_start
    assert s == pytest.approx(0.3) and prof.sweep_duration == dur
    tc = crossings(prof, s + 1e-4, s + dur - 1e-3) - s
    if log:
        # phi = 2 pi f0 T / ln r (r^(t/T) - 1), r = f1 / f0.
        lr = math.log(f1 / f0)
        k_of = 2 * f0 * dur / lr * np.expm1(lr * tc / dur)
        f_of = f0 * (f1 / f0) ** (tc / dur)
    else:
        # phi = 2 pi (f0 t + (f1 - f0) t^2 / (2 T)).
        k_of = 2 * (f0 * tc + 0.5 * (f1 - f0) * tc * tc / dur)
        f_of = f0 + (f1 - f0) * tc / dur
    k = np.rint(k_of)
    assert np.array_equal(k, np.arange(1, len(k) + 1))      # every crossing, in order
    # A crossing's time within 2e-7 s (linear interpolation on a 2 us grid of a
    # sine at <= 80 Hz: error < (2 pi 80 x 2 us)^2 / 8 x 2 us); the phase error is
    # 2 pi f dt_err, under 1e-4 of pi.
    assert np.max(np.abs(k_of - k) / (2 * f_of)) < 2e-7
    # The instantaneous frequency of the profile is the closed form's.
    assert prof.frequency(s + tc) == pytest.approx(f_of, rel=1e-12)
    assert np.isnan(prof.frequency([s - 0.1, s + dur + 0.1])).all()


def test_the_multisine_has_its_lines_only_and_a_low_crest_factor():
    p = load_preset('tr12x3')
    fmin, fmax, lines = 2.0, 150.0, 40
    prof = E.make_profile('multisine', p, fmin=fmin, fmax=fmax, lines=lines, periods=2)
    period = prof.options['period']
    assert period == pytest.approx(1.0 / fmin)
    # One steady period (after the fade-in period), sampled 8192 times.
    n = 8192
    t = prof.sweep_start + period + np.arange(n) * (period / n)
    v = prof.values(t) - prof.options['offset']
    spec = np.fft.rfft(v) / n * 2
    on = np.abs(spec) > 1e-9 * np.abs(spec).max()
    # The documented line set: log-spaced in [fmin, fmax], rounded to harmonics.
    want = np.unique(np.rint(np.geomspace(fmin, fmax, lines) * period).astype(int))
    assert np.array_equal(np.flatnonzero(on), want)
    a = np.abs(spec[on])
    assert np.ptp(a) < 1e-9 * a.mean()                       # equal amplitudes
    # The peak is the amplitude option (on a fine grid, within its sampling
    # error (2 pi fmax dt)^2 / 8 x peak), the RMS that of n equal lines.
    tt = prof.sweep_start + period + np.linspace(0.0, period, 2_000_001)
    peak = np.max(np.abs(prof.values(tt) - prof.options['offset']))
    amp = prof.options['amplitude']
    assert amp * (1 - 1e-6) <= peak <= amp * (1 + 1e-12)
    rms = a.mean() * math.sqrt(len(a) / 2)
    assert np.sqrt(np.mean(v * v)) == pytest.approx(rms, rel=1e-9)
    crest = peak / rms
    # Equal lines in phase would peak at sqrt(2 n) (7.5 for these 28), with
    # Schroeder's phases at about 3 on log-spaced lines; the profile's stay
    # below 2.5, near the 1.4 - 2 of designs on consecutive harmonics.
    assert len(a) == 28 and crest < 2.5


@pytest.mark.parametrize('preset', PRESETS)
@pytest.mark.parametrize('name', ['chirp', 'multisine'])
@pytest.mark.parametrize('command', COMMANDS)
def test_defaults_respect_the_limits_and_the_stroke(preset, name, command):
    p = load_preset(preset)
    prof = E.make_profile(name, p, command=command)
    o = prof.options
    assert prof.kind == command and prof.topic == f'{command}_command'
    dt = 1.0 / (40 * o['fmax'])
    t = np.arange(-0.1, prof.duration + 0.1, dt)
    v = prof.values(t)
    lo, hi = room(p)
    assert np.max(np.abs(v - o['offset'])) <= o['amplitude'] * (1 + 1e-12) or command == \
        'velocity'                                  # the return move after the sweep
    assert v[0] == v[-1] == pytest.approx(o['offset'], abs=1e-15)      # at rest
    if command == 'torque':
        assert np.max(np.abs(v)) <= p.max_torque
    elif command == 'velocity':
        assert np.max(np.abs(v)) <= nut_speed_limit(p)
        # The travel it commands (trapezoid rule on the 40-per-period grid) stays in
        # the stroke and comes back to the start (the return move; 1e-5 of the
        # stroke covers the rule's error); during a chirp within 2 A / (pi fmin).
        x = p.initial_position + np.concatenate(([0.0], np.cumsum(0.5 * dt * (v[1:] + v[:-1]))))
        assert lo <= x.min() and x.max() <= hi
        assert abs(x[-1] - p.initial_position) < 1e-5 * (p.stroke_max - p.stroke_min)
        if name == 'chirp':
            sweep = (t >= prof.sweep_start) & (t <= prof.sweep_start + prof.sweep_duration)
            bound = 2 * o['amplitude'] / (math.pi * o['fmin'])
            assert np.max(np.abs(x[sweep] - p.initial_position)) <= bound * 1.001
    else:
        assert lo <= v.min() and v.max() <= hi
        assert np.max(np.abs(np.diff(v))) / dt <= nut_speed_limit(p)


def test_band_and_amplitude_default_from_the_drive_and_the_limits():
    p = load_preset('tr12x3')
    j_total = p.motor_inertia + p.screw_inertia + p.moving_mass * (p.lead / (2 * math.pi)) ** 2
    f_v, f_p = p.velocity_gain / (2 * math.pi * j_total), p.position_gain / (2 * math.pi)
    chirp = E.make_profile('chirp', p)
    assert chirp.options['fmax'] == pytest.approx(2 * f_v, rel=1e-9)
    assert chirp.options['fmin'] == pytest.approx(2 * f_v / 100, rel=1e-9)
    assert chirp.options['duration'] == pytest.approx(10 / chirp.options['fmin'], rel=1e-9)
    # A quarter of the nut speed limit fits this stroke (bound 2 A / (pi fmin)).
    assert chirp.options['amplitude'] == pytest.approx(0.25 * nut_speed_limit(p), rel=1e-9)
    pos = E.make_profile('multisine', p, command='position')
    assert pos.options['fmax'] == pytest.approx(2 * f_p, rel=1e-9)
    assert pos.options['offset'] == p.initial_position
    # A command rate of 10 fmax within [100, 1000] Hz, never below 2.5 fmax.
    assert chirp.command_rate == 1000.0 and pos.command_rate == pytest.approx(10 * 2 * f_p)
    # An encoder raises a small default to 100 counts of motion at fmax.
    coarse = ScrewParams.from_dict(dict(encoder_counts=16), base=p)
    c = E.make_profile('chirp', coarse, fmin=1.0, fmax=10.0, amplitude=None)
    floor = 100 * p.lead / 16 * 2 * math.pi * 10           # 100 counts at 10 Hz [m/s]
    assert c.options['amplitude'] == pytest.approx(min(floor, 0.99 * nut_speed_limit(p)))


@pytest.mark.parametrize('preset', ['tr12x3', 'stick_slip'])
@pytest.mark.parametrize('command', COMMANDS)
def test_scalar_and_vector_values_agree_bit_for_bit(preset, command):
    for name in ('chirp', 'multisine'):
        prof = E.make_profile(name, load_preset(preset), command=command)
        t = np.random.default_rng(4).uniform(-1.0, prof.duration + 1.0, 1500)
        assert prof.values(t).tobytes() == np.array([prof(float(x)) for x in t]).tobytes()


@pytest.mark.parametrize('name, options, fragment', [
    ('chirp', dict(fmin=50.0, fmax=10.0), "option 'fmax' = 10.0 Hz: must exceed fmin 50 Hz"),
    ('chirp', dict(amplitude=1.0), "option 'amplitude' = 1.0 m/s: with offset 0 m/s exceeds "
     'the nut speed of velocity_limit'),
    ('chirp', dict(amplitude=0.1, fmin=0.05, fmax=5.0), "option 'amplitude' = 0.1 m/s: "
     'commands a travel of'),
    ('chirp', dict(command='torque', amplitude=5.0), "option 'amplitude' = 5.0 N m: with "
     'offset 0 N m exceeds max_torque'),
    ('chirp', dict(command='position', amplitude=0.01, fmax=50.0), "option 'amplitude' = "
     '0.01 m: moves the target at up to'),
    ('multisine', dict(command='position', amplitude=1.0), "option 'amplitude' = 1.0 m: "
     'around offset 0 m leaves'),
    ('multisine', dict(period=0.1, fmin=1.0), "option 'period' = 0.1 s: is shorter than "
     '1 / fmin = 1 s'),
    ('multisine', dict(command='speed'), "option 'command' = 'speed': must be torque, velocity "
     'or position'),
    ('multisine', dict(lines=0), "option 'lines' = 0 -: must lie in [1, 100000]"),
])
def test_bad_options_raise_one_clear_error(name, options, fragment):
    assert_one_clear_error(name, options, fragment)


def test_excite_refuses_a_command_rate_that_cannot_carry_the_band():
    r = cli('excite', 'chirp', '--opt', 'fmax=100', '--command-rate', '100', '--dry-run', '3')
    err = r.stderr.strip().splitlines()
    assert r.returncode == 1 and len(err) == 1, r.stdout + r.stderr
    assert err[0] == ('leadscrew_sim: error: --command-rate 100 Hz is below 2.5 fmax = 250 Hz '
                      'of the chirp: raise it or lower --opt fmax')
