"""
The stepper at rest and after one step (doc/model.md section 18), against closed forms.

Oracles:
- static torque: at rest under a load torque T_L the rotor sits where the
  motor's torque balances it, T_L = T_h sin(N_r d) + T_d sin(4 N_r (theta -
  theta_0)) with T_h = K_m I at the current I set (run, or hold after the
  standstill time), d the rotor's displacement from the commanded microstep
  (the windings carry exactly their set points at rest);
- single-step ringing: after one full step the rotor rings at the
  small-signal frequency sqrt(N_r (T_h + 4 T_d) / J_total), J_total = J_m +
  J_s + (m_n + m_p) (l / 2 pi)^2 with the screw and the nut through the lead;
- the step generator: a position target is reached along the trapezoid of
  max_step_rate and step_acceleration (closed form), a velocity command along
  a ramp of step_acceleration; the commanded angle is a whole microstep.
"""
import math

import numpy as np
import pytest

from stepper_axes import (motor_inertia_total, new_model, position_rows, rigid_axis,
                          run_commands, velocity_rows)


def settle_under_load(p, load, microstep=0, seconds=0.8):
    """
    Hold microstep ``microstep`` under a load torque [N m] ramped in over 0.2 s; return the run.

    The load is an axial force on the nut, -load / rt (frictionless thread: the
    torque on the motor is exactly load, against +theta).
    """
    m, th0 = new_model(p)
    n = int(round(seconds / 1e-3))
    target = th0 + microstep * p.step_angle / p.microsteps
    ramp = np.minimum(np.arange(1, n + 1) / 200.0, 1.0)
    forces = -load / p.lead_ratio * ramp
    return m, th0, run_commands(m, position_rows(n, target), forces)


@pytest.mark.parametrize('microstep', [0, 5])
@pytest.mark.parametrize('share', [0.1, 0.35, 0.6, 0.85])
def test_static_torque_against_displacement(share, microstep):
    """A rotor at rest carries T_L = -(T_h sin(N_r d) + T_d sin(4 N_r theta)), within 1 %."""
    p = rigid_axis(rotor_damping=3e-3, hold_current_delay=10.0)
    load = share * p.holding_torque
    m, th0, r = settle_under_load(p, load, microstep)
    n_r = p.rotor_teeth
    d = r['motor_angle'][-1] - r['step_position'][-1]
    assert abs(r['motor_velocity'][-1]) < 1e-6
    assert r['step_position'][-1] == pytest.approx(th0 + microstep * p.step_angle / p.microsteps,
                                                   abs=1e-12)
    restoring = (p.holding_torque * math.sin(n_r * d)
                 + p.detent_torque * math.sin(4.0 * n_r * (r['motor_angle'][-1] - th0)))
    assert -restoring == pytest.approx(load, rel=0.01), (share, microstep, d)
    assert r['current_set'][-1] == p.run_current


def test_static_torque_at_the_hold_current():
    """After the standstill time the current drops to hold_current: T_h scales with it (1 %)."""
    p = rigid_axis(rotor_damping=3e-3, hold_current_delay=0.3)
    load = 0.6 * p.holding_torque * p.hold_current / p.run_current
    m, th0, r = settle_under_load(p, load, seconds=1.5)
    assert r['current_set'][250] == p.run_current       # before the delay
    assert r['current_set'][-1] == p.hold_current
    d = r['motor_angle'][-1] - r['step_position'][-1]
    n_r = p.rotor_teeth
    t_h = p.holding_torque * p.hold_current / p.run_current
    restoring = (t_h * math.sin(n_r * d)
                 + p.detent_torque * math.sin(4.0 * n_r * (r['motor_angle'][-1] - th0)))
    assert -restoring == pytest.approx(load, rel=0.01)
    assert math.hypot(r['phase_current_a'][-1], r['phase_current_b'][-1]) == pytest.approx(
        p.hold_current, rel=1e-9)


def zero_crossings(t, y):
    """Return the times where y changes sign (linear interpolation)."""
    s = np.flatnonzero(np.sign(y[:-1]) * np.sign(y[1:]) < 0)
    return t[s] - y[s] * (t[s + 1] - t[s]) / (y[s + 1] - y[s])


@pytest.mark.parametrize('payload', [0.5, 3.0])
def test_single_step_rings_at_the_small_signal_frequency(payload):
    """
    One full step rings at sqrt(N_r (T_h + 4 T_d) / J_total), J_total through the lead (2 %).

    A full step starts the swing at a quarter electrical cycle, where the sine
    torque makes the period longer (a pendulum's); the frequency is measured
    on the ring-down once the swing is below 0.1 rad electrical, with about 5 %
    of critical damping (a shift of 0.1 %).
    """
    p = rigid_axis(microsteps=1, payload_mass=payload, step_acceleration=1e6,
                   hold_current_delay=10.0)
    j = motor_inertia_total(p)
    w_n = math.sqrt(p.rotor_teeth * (p.holding_torque + 4.0 * p.detent_torque) / j)
    p = p.replace(rotor_damping=2.0 * 0.05 * j * w_n)
    dt = 2e-5
    m, th0 = new_model(p, dt=dt)
    n = int(round(0.15 / dt))
    r = run_commands(m, position_rows(n, th0 + p.step_angle))
    t = np.arange(1, n + 1) * dt
    assert r['step_position'][-1] == pytest.approx(th0 + p.step_angle, abs=1e-12)
    y = r['motor_angle'] - (th0 + p.step_angle)
    crossings = zero_crossings(t, y)
    idx = np.searchsorted(t, crossings)
    swing = np.array([np.max(np.abs(y[a:b])) for a, b in zip(idx[:-1], idx[1:])])
    small = np.flatnonzero(p.rotor_teeth * swing < 0.1)
    assert len(small) >= 8, swing
    periods = 2.0 * np.diff(crossings)[small[:8]]
    w_sim = 2.0 * math.pi / np.mean(periods)
    print(f'payload {payload} kg: J_total {j:.4g} kg m^2, ringing {w_sim / (2 * math.pi):.2f} '
          f'Hz, small-signal {w_n / (2 * math.pi):.2f} Hz')
    assert w_sim == pytest.approx(w_n, rel=0.02)
    assert abs(y[-1]) < 1e-3 * p.step_angle


def trapezoid(t, distance, v, a):
    """Return the closed-form trapezoid's position [rad] (a triangle when short) at t [s]."""
    v = min(v, math.sqrt(distance * a))
    t1 = v / a
    t2 = distance / v
    t3 = t2 + t1
    out = np.where(t < t1, 0.5 * a * t * t,
                   np.where(t < t2, 0.5 * a * t1 * t1 + v * (t - t1),
                            np.where(t < t3, distance - 0.5 * a * (t3 - t) ** 2, distance)))
    return out, t3


@pytest.mark.parametrize('full_steps', [37.0, 2000.0])
def test_position_target_follows_the_trapezoid(full_steps):
    """The commanded angle follows the trapezoid of max_step_rate and step_acceleration."""
    p = rigid_axis(rotor_damping=1e-3)
    m, th0 = new_model(p)
    w = p.max_step_rate * p.step_angle
    a = p.step_acceleration * p.step_angle
    dist = full_steps * p.step_angle
    ref, t_end = trapezoid(np.arange(1, 3001) * 1e-3, dist, w, a)
    r = run_commands(m, position_rows(3000, th0 + dist))
    cmd = r['step_position'] - th0
    micro = p.step_angle / p.microsteps
    assert np.max(np.abs(cmd - ref)) < 1.0 * micro + w * 2 * m.substep
    k = np.round(cmd / micro)
    assert np.max(np.abs(cmd - k * micro)) < 1e-9          # whole microsteps
    assert np.max(np.abs(r['step_rate'])) <= w * (1 + 1e-12)
    assert cmd[-1] == pytest.approx(dist, abs=1e-12)
    assert r['lost_full_steps'].max() == 0
    assert r['motor_angle'][-1] - th0 == pytest.approx(dist, abs=0.02 * p.step_angle)
    assert np.flatnonzero(np.abs(cmd - dist) < 1e-12)[0] * 1e-3 <= t_end + 2e-3


def test_velocity_command_ramps_at_the_step_acceleration():
    """A velocity command ramps the step rate at step_acceleration, up and back down."""
    p = rigid_axis(rotor_damping=1e-3)
    m, th0 = new_model(p)
    w = 0.6 * p.max_step_rate * p.step_angle
    a = p.step_acceleration * p.step_angle
    rows = np.concatenate([velocity_rows(300, w), velocity_rows(300, 0.0)])
    r = run_commands(m, rows)
    t = np.arange(1, 601) * 1e-3
    up = np.minimum(a * t, w)
    down = np.maximum(w - a * (t - 0.3), 0.0)
    expect = np.where(t <= 0.3, up, down)
    assert np.max(np.abs(r['step_rate'] - expect)) <= a * 2 * m.substep
    assert r['step_rate'][-1] == 0.0
    assert r['lost_full_steps'].max() == 0
    with pytest.raises(ValueError, match='torque'):
        m.command('torque', effort=0.1)


@pytest.mark.parametrize('preset', ['nema17_tr8x8', 'nema23_tr12x3'])
def test_energy_balance_of_a_stepper_move(preset):
    """The motor's work (its torque with detent and damping) balances the energy terms."""
    from leadscrew_sim import LeadScrewModel, load_preset
    p = load_preset(preset)
    m = LeadScrewModel(p)
    th0 = m.output().motor_angle
    run_commands(m, position_rows(2000, th0 + p.hand_sign * 6.0 * math.pi))   # 3 turns up
    e = m.energy()
    flow = abs(e['input_work']) + abs(e['potential']) + e['friction_dissipation']
    assert e['potential'] > 0.0
    assert abs(e['residual']) < 1e-3 * flow, e
