"""
The identification profiles: limits, directions, durations, values, options and interfaces.

Every profile of every preset, with its defaults, is sampled on a fine grid
and at its segment ends; the oracles are the axis limits, closed-form
durations counted from the options, the scalar and vectorised forms against
each other bit for bit, and the topic table of the io layer.
"""
import math

from leadscrew_sim import LeadScrewModel, load_preset
from leadscrew_sim.analysis.excitation import profiles as E
from leadscrew_sim.core.fields import ParameterError
from leadscrew_sim.core.params import ScrewParams
from leadscrew_sim.io.topics import TOPIC_SPECS
import numpy as np
import pytest

PRESETS = ('tr12x3', 'tr8x8', 'stick_slip', 'anti_backlash', 'seed_a', 'seed_c')


def grid(profile, n=200001):
    """Return sample times over the profile and a little beyond, with every segment end."""
    ends = [s.t0 for s in profile.segments] + [s.t1 for s in profile.segments]
    t = np.concatenate((np.linspace(-1.0, profile.duration + 1.0, n), ends))
    return np.sort(t)


def nut_speed_limit(p):
    """Return the nut speed [m/s] of the motor velocity limit: omega_max l / (2 pi)."""
    return p.velocity_limit * p.pitch * p.starts / (2.0 * math.pi)


@pytest.mark.parametrize('preset', PRESETS)
@pytest.mark.parametrize('name', sorted(E.PROFILES))
def test_values_stay_inside_the_stroke_and_the_limits(preset, name):
    p = load_preset(preset)
    prof = E.make_profile(name, p)
    t = grid(prof)
    v = prof.values(t)
    assert np.all(np.isfinite(v))
    if prof.kind == 'torque':
        assert np.max(np.abs(v)) <= p.max_torque
    elif prof.kind == 'velocity':
        assert np.max(np.abs(v)) <= nut_speed_limit(p)
        # The nut travel the speeds command, integrated on a 10 us grid (error
        # < 10 us x v_max per level edge, below 1e-6 of the stroke), stays inside
        # the stroke and comes back to the start.
        dt = 1e-5
        tt = np.arange(0.0, prof.duration, dt)
        x = p.initial_position + np.cumsum(prof.values(tt)) * dt
        assert p.stroke_min < x.min() and x.max() < p.stroke_max
        assert abs(x[-1] - p.initial_position) < 1e-6 * (p.stroke_max - p.stroke_min)
    else:
        assert p.stroke_min < v.min() and v.max() < p.stroke_max
        speeds = np.abs(np.diff(v)) / np.maximum(np.diff(t), 1e-300)
        # Between two grid points the target moves at the move speed at most
        # (a segment end on the grid has a zero time step: left out).
        assert np.max(speeds[np.diff(t) > 1e-9]) <= prof.options['speed'] * (1 + 1e-9)
        assert prof.options['speed'] <= nut_speed_limit(p)
    # The profile starts and ends at rest: the centre torque, zero speed, the start position.
    rest = {'torque': prof.options.get('center'), 'velocity': 0.0,
            'position': p.initial_position}[prof.kind]
    assert v[-1] == pytest.approx(rest, abs=1e-15)


@pytest.mark.parametrize('name', sorted(E.PROFILES))
def test_both_directions_are_present(name):
    p = load_preset('tr12x3')
    prof = E.make_profile(name, p)
    v = prof.values(grid(prof))
    if prof.kind == 'torque':
        c = prof.options['center']
        assert v.max() > c and v.min() < c
    elif prof.kind == 'velocity':
        assert v.max() > 0 and v.min() < 0
        if name != 'sweep':             # chirp, multisine: test_excitation_broadband
            return
        # The same speeds in both directions, each held equally long.
        assert sorted(np.unique(v[v > 0])) == sorted(-np.unique(v[v < 0]))
        # Equal times per direction on a uniform grid: each level edge can move a
        # sample from one side to the other, so they differ by 2 per level at most.
        u = prof.values(np.linspace(0.0, prof.duration, 100000, endpoint=False))
        assert abs(np.sum(u > 0) - np.sum(u < 0)) <= 2 * prof.options['levels']
    else:
        d = np.diff(v)
        assert np.any(d > 0) and np.any(d < 0)


def test_durations_are_those_counted_from_the_options():
    p = load_preset('tr12x3')
    b = E.make_profile('breakaway', p, ramp_time=1.5, dwell=0.25)
    assert b.duration == pytest.approx(3 * 0.25 + 4 * 1.5, rel=1e-12)
    s = E.make_profile('sweep', p, levels=5, settle=0.2, measure=0.4, stop=0.1)
    assert s.duration == pytest.approx(2 * 5 * (0.2 + 0.4) + 0.1, rel=1e-12)
    # Reversals from the centre: out and back to each side, 4 a of travel and
    # 4 dwells per cycle.
    a, n, dw, v = 3e-4, 4, 0.3, 2e-3
    r = E.make_profile('reversals', p, amplitude=a, cycles=n, dwell=dw, speed=v)
    assert r.duration == pytest.approx(4 * a * n / v + 4 * n * dw, rel=1e-9)
    # ISO 230-2: from x0 to P1 - o, each cycle up and down over travel + 2 o,
    # back to x0; 2 m dwells per cycle and a final dwell of min(dwell, 0.5 s).
    m, cyc, trav, o, dw, v, c = 4, 3, 0.02, 1e-3, 0.7, 0.01, 0.01
    iso = E.make_profile('iso230', p, targets=m, cycles=cyc, travel=trav, overshoot=o,
                         dwell=dw, speed=v, center=c)
    first = c - trav / 2 - o
    distance = 2 * abs(first - p.initial_position) + cyc * 2 * (trav + 2 * o)
    assert iso.duration == pytest.approx(distance / v + 2 * m * cyc * dw + 0.5, rel=1e-9)
    targets = iso.target_positions()
    assert len(targets) == m and targets[0] == pytest.approx(c - trav / 2)
    assert targets[-1] == pytest.approx(c + trav / 2) and np.all(np.diff(targets) > 0)
    # Interior targets within a tenth of the spacing of the even grid (irregular spacing).
    even = np.linspace(c - trav / 2, c + trav / 2, m)
    assert np.max(np.abs(np.array(targets) - even)) <= 0.1 * trav / (m - 1) + 1e-15


@pytest.mark.parametrize('name', sorted(E.PROFILES))
def test_vectorised_values_equal_the_scalar_call_bit_for_bit(name):
    prof = E.make_profile(name, load_preset('stick_slip'))
    rng = np.random.default_rng(7)
    t = np.concatenate((rng.uniform(-1.0, prof.duration + 1.0, 3000),
                        [s.t0 for s in prof.segments], [s.t1 for s in prof.segments]))
    vec = prof.values(t)
    scalar = np.array([prof(float(x)) for x in t])
    assert vec.tobytes() == scalar.tobytes()


@pytest.mark.parametrize('name, options, fragment', [
    ('sweep', dict(v_min=float('nan')), "option 'v_min' = nan m/s: must lie in"),
    ('sweep', dict(levels=2.5), "option 'levels' = 2.5: must be a whole number"),
    ('sweep', dict(v_max=10.0), "option 'v_max' = 10.0 m/s: exceeds the nut speed of "
     'velocity_limit'),
    ('sweep', dict(v_max=0.1, measure=5.0), "option 'v_max' = 0.1 m/s: makes a travel of"),
    ('sweep', dict(first=0), "option 'first' = 0 -: must be +1 or -1"),
    ('breakaway', dict(peak=2.0), "option 'peak' = 2.0 N m: with centre 0 N m exceeds "
     'max_torque'),
    ('breakaway', dict(ramp_time=-1.0), "option 'ramp_time' = -1.0 s: must lie in [0.01, 3600]"),
    ('reversals', dict(amplitude=0.5), "option 'amplitude' = 0.5 m: around centre 0 m leaves"),
    ('reversals', dict(speed='fast'), "option 'speed' = 'fast': not a number"),
    ('iso230', dict(travel=1.0), "option 'travel' = 1.0 m: with overshoot"),
    ('iso230', dict(targets=1), "option 'targets' = 1 -: must lie in [2, 1000]"),
    ('iso230', dict(bogus=1), "option 'bogus' is unknown (options: center, travel"),
])
def test_bad_options_raise_one_clear_error(name, options, fragment):
    assert_one_clear_error(name, options, fragment)


def assert_one_clear_error(name, options, fragment):
    """Assert that the profile refuses the options with one line naming it and the fragment."""
    with pytest.raises(E.ProfileError) as info:
        E.make_profile(name, load_preset('tr12x3'), **options)
    msg = str(info.value)
    assert msg.startswith(f"excitation '{name}': ") and fragment in msg, msg
    assert '\n' not in msg
    assert isinstance(info.value, ParameterError)      # the CLI's one-line error path


def test_unknown_profile_and_immutability():
    with pytest.raises(E.ProfileError, match="unknown excitation profile 'prbs'"):
        E.make_profile('prbs', load_preset('tr12x3'))
    prof = E.make_profile('sweep', load_preset('tr12x3'))
    with pytest.raises(AttributeError):
        prof.duration_scale = 2.0
    with pytest.raises(AttributeError):
        prof.segments = ()


def test_registry_kinds_and_topics_match_the_topic_table():
    kinds = {'breakaway': 'torque', 'sweep': 'velocity', 'reversals': 'position',
             'iso230': 'position', 'warmup': 'position', 'chirp': 'velocity',
             'multisine': 'velocity'}
    assert {n: c.kind for n, c in E.PROFILES.items()} == kinds
    p = load_preset('tr12x3')
    for name in E.PROFILES:
        prof = E.make_profile(name, p)
        assert prof.topic == f'{prof.kind}_command'
        assert TOPIC_SPECS[prof.topic][0] == 'std_msgs/msg/Float64'


def test_simulate_interfaces_torque_and_drive_sources():
    p = load_preset('tr12x3')
    b = E.make_profile('breakaway', p)
    fn = b.torque_source()
    assert fn.needs_state
    # A standing nut: the planned ramp.
    for t in (0.0, 0.7, 1.9, 3.3, 6.0):
        assert fn(int(t * 1000), t, 0.0, 0.0) == b(t)
    # Once the nut moved abort_travel on a ramp, that direction's torque is the centre.
    t_up = b.options['dwell'] + 0.5
    fn(0, t_up, 0.0, 0.0)
    assert fn(0, t_up + 0.1, 2 * b.options['abort_travel'], 0.0) == b.options['center']
    assert fn(0, t_up + 1.0, 0.0, 0.0) == b.options['center']
    for name, topic in (('sweep', 'velocity_command'), ('reversals', 'position_command')):
        prof = E.make_profile(name, p)
        src, tp, desc = prof.drive_source()
        assert tp == topic and desc.startswith(f'excite={name} ')
        x, v = src(1.234)
        if name == 'sweep':
            assert math.isnan(x) and v == prof(1.234)
        else:
            assert math.isnan(v) and x == prof(1.234)
    with pytest.raises(ValueError):
        b.drive_source()
    with pytest.raises(ValueError):
        E.make_profile('sweep', p).torque_source()


def test_breakaway_controller_keeps_a_torque_driven_axis_from_running_away():
    # tr12x3 without backlash: past breakaway the thread slides with mu_k < mu_s,
    # so a torque held at the ramp's value accelerates the nut; the planned ramp
    # (open loop) drives it tens of mm, the controller stops it within a few
    # abort_travel (the nut coasts on after the torque returns to the centre).
    p = ScrewParams.from_dict(dict(backlash=0.0), base=load_preset('tr12x3'))
    prof = E.make_profile('breakaway', p, ramp_time=1.0, dwell=0.2)
    n = int(prof.duration / 1e-3)
    t = np.arange(n) * 1e-3
    open_loop = LeadScrewModel(p, dt=1e-3).run(prof.values(t))['nut_position']
    assert np.max(np.abs(open_loop - p.initial_position)) > 0.01
    m = LeadScrewModel(p, dt=1e-3)
    fn = prof.torque_source()
    x, xs = m.output().nut_position, []
    for k in range(n):
        m.advance(fn(k, t[k], x, None))
        x = m.output().nut_position
        xs.append(x)
    travel = np.max(np.abs(np.array(xs) - p.initial_position))
    assert prof.options['abort_travel'] < travel < 5 * prof.options['abort_travel']
