"""
The ageing of the axis (doc/model.md section 19): wear, lubricant, heat, growth.

Each test names its oracle: Archard's law integrated over the recorded flank
forces and sliding speeds, the backlash measured by reversals with an ideal
scale, the spring force from the simulated half-nut positions, the closed
form of a first-order thermal mass, the exponential decay of the lubricant in
the recorded sliding distance, the growth of a bar alpha dT (x - x_fixed).
"""
import math

import numpy as np
import pytest

from leadscrew_sim.core.engine import drive as D
from leadscrew_sim.core.model import LeadScrewModel
from leadscrew_sim.core.params import ParameterError
from leadscrew_sim.core.presets import load_preset


def _velocity_rows(p, v):
    """Drive command rows asking the nut velocities v [m/s] (velocity mode, theta sense)."""
    rows = np.full((len(v), 4), np.nan)
    rows[:, 0] = D.MODE_VELOCITY
    rows[:, 2] = np.asarray(v) / p.lead_ratio * p.hand_sign
    return rows


def _square(n, dt, speed, half_period):
    t = np.arange(n) * dt
    return np.where((t // half_period) % 2 == 0, speed, -speed)


def _scale_gap(p, r):
    """Return the scale's nut position less the encoder's through the lead [m]."""
    return r['sensor_nut_position'] - p.lead_ratio * p.hand_sign * r['sensor_screw_angle']


def _phase_ends(v):
    """Return the indices of the last step of each constant-velocity phase."""
    return np.flatnonzero(np.diff(v) != 0.0)


# Flank wear ------------------------------------------------------------------------------

def test_flank_wear_is_archard_and_opens_the_backlash():
    """Wear = rate N |v_s| dt summed; reversals with the scale see b plus both flanks' wear."""
    p = load_preset('tr12x3', inclination=0.0, guide_coulomb=20.0, wear_rate=1e-12,
                    ageing_speedup=1e6)
    m = LeadScrewModel(p)
    n = 20000
    v = _square(n, m.dt, 0.01, 2.0)
    r = m.run(None, commands=_velocity_rows(p, v))
    k = p.wear_rate * p.ageing_speedup
    slide = np.abs(r['sliding_velocity']) * m.dt
    for flank, normal in (('wear_leading_a', 'normal_leading'),
                          ('wear_trailing_a', 'normal_trailing')):
        oracle = np.cumsum(k * r[normal] * slide)
        assert oracle[-1] > 1e-5          # both flanks wore 10 um and more
        np.testing.assert_allclose(r[flank][1000:], oracle[1000:], rtol=0.01)
    # the lost motion at the last reversal: the gap between the ends of the last two phases;
    # the flank penetrations (20 N / 1e8 N/m) are 0.2 % of it
    ends = _phase_ends(v)
    gap = _scale_gap(p, r)
    lost = abs(gap[ends[-1]] - gap[-1])
    worn = p.backlash + r['wear_leading_a'][-1] + r['wear_trailing_a'][-1]
    assert worn > 1.4 * p.backlash
    assert lost == pytest.approx(worn, rel=0.01)
    assert r['backlash'][-1] == pytest.approx(worn, rel=1e-12)


def test_a_split_nut_loses_its_preload_before_its_backlash_opens():
    """The spring (from the half-nut positions) relaxes by k_p times the wear; then play opens."""
    p = load_preset('anti_backlash', guide_coulomb=2.0, preload_stiffness=4e5,
                    wear_rate=1e-12, ageing_speedup=2e6)
    m = LeadScrewModel(p)
    n = 8000
    v = _square(n, m.dt, 0.02, 1.0)
    r = m.run(None, commands=_velocity_rows(p, v))
    worn = r['wear_leading_a'] + r['wear_trailing_b']     # the preloaded flanks
    spring = p.preload_force + p.preload_stiffness * (
        p.backlash - (r['nut_b_position'] - r['nut_position']))
    ends = _phase_ends(v)
    # while the preload is up, the spring force is f_p - k_p (w + the two flanks'
    # penetrations, their in-plane force over k) at every phase end, and there is no play
    cl = math.cos(p.lead_angle)
    pen = (r['normal_leading'] + r['normal_trailing_b']) * cl / p.contact_stiffness
    preload = p.preload_force - p.preload_stiffness * (worn + pen)
    assert preload[ends[-1]] < 0.8 * p.preload_force      # the spring did relax
    np.testing.assert_allclose(spring[ends], preload[ends], atol=0.01)
    gap = _scale_gap(p, r)
    lost = np.abs(np.diff(gap[ends]))
    # (the play of the set backlash b, were the preload gone; what moves is the wear of one
    # phase, about 1 um, and the flanks' give)
    assert lost.max() < 0.05 * p.backlash
    # wear on at a higher rate: the preload goes, and the play opens by the wear past f_p / k_p
    m.set_params(p.replace(ageing_speedup=2e7))
    r2 = m.run(None, commands=_velocity_rows(p, _square(30000, m.dt, 0.02, 1.0)))
    assert r2['preload'][-1] == 0.0
    gap2 = _scale_gap(p, r2)
    ends2 = _phase_ends(_square(30000, m.dt, 0.02, 1.0))
    lost2 = abs(gap2[ends2[-1]] - gap2[-1])
    expected = r2['backlash'][-1] + p.guide_coulomb / p.preload_stiffness   # + the spring's give
    assert r2['backlash'][-1] > 0.5 * p.backlash
    assert lost2 == pytest.approx(expected, rel=0.1)


# Lubricant ------------------------------------------------------------------------------

def test_the_lubricant_decays_in_the_sliding_distance_and_friction_follows():
    """L = exp(-s / life), mu = L mu + (1 - L) mu_dry; the thread's friction ratio follows."""
    p = load_preset('tr12x3', lubricant_life=2.0, ageing_speedup=10.0, mu_k_dry=0.3,
                    mu_s_dry=0.35)
    m = LeadScrewModel(p)
    n = 3000
    r = m.run(None, commands=_velocity_rows(p, np.full(n, 0.02)))
    s = np.cumsum(np.abs(r['sliding_velocity']) * m.dt)
    L = np.exp(-s * p.ageing_speedup / p.lubricant_life)
    assert L[-1] < 0.05
    np.testing.assert_allclose(r['lubricant'], L, rtol=1e-9, atol=1e-15)
    np.testing.assert_allclose(r['mu_k'], p.mu_k_dry + (p.mu_k - p.mu_k_dry) * L, rtol=1e-9)
    np.testing.assert_allclose(r['mu_s'], p.mu_s_dry + (p.mu_s - p.mu_s_dry) * L, rtol=1e-9)
    # sliding well above the Stribeck velocity, the thread's friction over its normal force
    # is mu_k' = mu_k / cos(psi_n) of the step before (the step's friction acts first)
    sliding = np.abs(r['sliding_velocity']) > 50 * p.stribeck_velocity
    ratio = np.abs(r['friction_force']) / (r['normal_leading'] + r['normal_trailing'])
    i = np.flatnonzero(sliding)[1:]
    np.testing.assert_allclose(ratio[i], r['mu_k'][i - 1] * p.thread_factor, rtol=0.01)
    m.relubricate()
    assert m.ageing_state()['lubricant'] == 1.0
    r = m.run(None, commands=_velocity_rows(p, np.full(2, 0.02)))
    assert r['lubricant'][0] > 0.998
    assert r['mu_k'][0] == pytest.approx(
        p.mu_k_dry + (p.mu_k - p.mu_k_dry) * r['lubricant'][0], rel=1e-9)


# Heat and thermal growth -----------------------------------------------------------------

def test_the_screw_heats_as_a_first_order_mass_and_takes_its_share_of_friction():
    """T = T_amb + (P/G)(1 - exp(-t G / C)); heat flow = heat_to_screw times friction power."""
    speedup = 10.0
    p = load_preset('tr12x3', guide_coulomb=0.0, screw_heat_capacity=20.0, screw_heat_loss=1.0,
                    heat_to_screw=0.6, ambient_temperature=22.0, ageing_speedup=speedup)
    m = LeadScrewModel(p)
    n = 6000
    r = m.run(None, commands=_velocity_rows(p, np.full(n, 0.01)))
    # the energy accounting: friction dissipated per step (thread and bearing, no guide)
    power = np.diff(r['friction_dissipation']) / m.dt
    np.testing.assert_allclose(r['heat_flow'][1:][500:], p.heat_to_screw * power[500:],
                               rtol=0.01)
    # a constant heat flow from 0.5 s on (the speed settled): the closed form from there
    i0 = 500
    P = r['heat_flow'][i0:].mean()
    assert np.ptp(r['heat_flow'][i0:]) < 0.01 * P
    C = p.screw_heat_capacity / speedup
    G = p.screw_heat_loss
    t = (np.arange(n - i0) + 1) * m.dt
    T0 = r['screw_temperature'][i0 - 1]
    closed = p.ambient_temperature + (T0 - p.ambient_temperature) * np.exp(-t * G / C) \
        + (P / G) * (1.0 - np.exp(-t * G / C))
    rise = closed[-1] - p.ambient_temperature
    assert rise > 0.5
    np.testing.assert_allclose(r['screw_temperature'][i0:] - p.ambient_temperature,
                               closed - p.ambient_temperature, rtol=0.01, atol=0.01 * rise)


def test_the_scale_sees_the_thermal_growth_and_the_encoder_does_not():
    """Scale = x + alpha dT (x - x_fixed); an open-loop twin at alpha 0 has the same encoder."""
    p = load_preset('tr12x3', screw_heat_capacity=1e6, fixed_bearing_x=-0.05,
                    linear_scale=True)
    warm = dict(LeadScrewModel(p).ageing_state(), screw_temperature=p.ambient_temperature + 40.0)
    torques = np.full(2000, 0.6)
    runs = {}
    for alpha in (p.thermal_expansion, 0.0):
        q = p.replace(thermal_expansion=alpha)
        runs[alpha] = LeadScrewModel(q, ageing=warm).run(torques)
    r, cold = runs[p.thermal_expansion], runs[0.0]
    assert abs(r['nut_position'][-1]) > 0.01
    growth = p.thermal_expansion * (r['screw_temperature'] - p.ambient_temperature) * (
        r['nut_position'] - p.fixed_bearing_x)
    np.testing.assert_allclose(r['thermal_growth'], growth, rtol=0.01)
    np.testing.assert_allclose(r['sensor_nut_position'] - r['nut_position'], growth, rtol=0.01)
    assert np.array_equal(r['sensor_screw_angle'], cold['sensor_screw_angle'])
    assert np.array_equal(cold['sensor_nut_position'], cold['nut_position'])


def test_a_scale_closed_loop_puts_the_grown_screw_s_nut_on_target():
    """Position loops on the encoder and on the scale end alpha dT (x - x_fixed) apart."""
    base = load_preset('tr12x3', screw_heat_capacity=1e6, linear_scale=True)
    warm = dict(LeadScrewModel(base).ageing_state(),
                screw_temperature=base.ambient_temperature + 30.0)
    target = 0.1
    ends = {}
    for feedback in ('motor_encoder', 'linear_scale'):
        p = base.replace(drive_feedback=feedback)
        m = LeadScrewModel(p, ageing=warm)
        rows = np.full((3000, 4), np.nan)
        rows[:, 0] = D.MODE_POSITION
        rows[:, 1] = m.nut_to_motor(target)
        r = m.run(None, commands=rows)
        ends[feedback] = r['nut_position'][-1]
    growth = base.thermal_expansion * 30.0 * target
    assert ends['motor_encoder'] - ends['linear_scale'] == pytest.approx(growth, rel=0.05)


# Determinism, reset, bad input -----------------------------------------------------------

def test_ageing_off_changes_nothing_and_a_reset_keeps_the_wear():
    """Zero rates leave the state as new; reset() keeps the wear, reset_ageing() renews it."""
    p = load_preset('tr12x3')
    m = LeadScrewModel(p)
    r = m.run(None, commands=_velocity_rows(p, np.full(500, 0.01)))
    assert m.ageing_state() == {'wear_leading_a': 0.0, 'wear_trailing_a': 0.0,
                                'wear_leading_b': 0.0, 'wear_trailing_b': 0.0,
                                'lubricant': 1.0, 'screw_temperature': p.ambient_temperature}
    assert np.all(r['backlash'] == p.backlash) and np.all(r['mu_k'] == pytest.approx(p.mu_k))
    aged = LeadScrewModel(p.replace(wear_rate=1e-9, ageing_speedup=100.0))
    aged.run(None, commands=_velocity_rows(p, np.full(500, 0.01)))
    worn = aged.ageing_state()
    assert worn['wear_leading_a'] > 0.0
    aged.reset()
    assert aged.ageing_state() == worn
    aged.reset_ageing()
    assert aged.ageing_state()['wear_leading_a'] == 0.0


@pytest.mark.parametrize('name, value, allowed', [
    ('wear_rate', -1e-12, '[0.0, 0.001]'),
    ('lubricant_life', -1.0, '[0.0, 1000000000000.0]'),
    ('screw_heat_capacity', -5.0, '[0.0, 100000000.0]'),
    ('screw_heat_loss', -0.1, '[0.0, 1000000.0]'),
    ('heat_to_screw', 1.5, '[0.0, 1.0]'),
    ('heat_to_screw', -0.1, '[0.0, 1.0]'),
    ('ageing_speedup', 0.0, '(0.0, 1000000000000.0]'),
    ('thermal_expansion', math.nan, 'finite'),
])
def test_bad_ageing_parameters_name_the_parameter_the_value_and_the_range(name, value,
                                                                          allowed):
    with pytest.raises(ParameterError) as err:
        load_preset('tr12x3', **{name: value})
    text = str(err.value)
    assert f"'{name}'" in text and allowed in text and (repr(value) in text or 'nan' in text)


def test_a_bad_ageing_state_is_refused_and_changes_nothing():
    m = LeadScrewModel(load_preset('tr12x3'))
    before = m.ageing_state()
    with pytest.raises(ParameterError, match="'lubricant'.*1.5.*0.0, 1.0"):
        m.set_ageing_state(dict(before, lubricant=1.5))
    with pytest.raises(ParameterError, match='missing'):
        m.set_ageing_state({'lubricant': 1.0})
    assert m.ageing_state() == before
