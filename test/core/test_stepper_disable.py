"""
A disabled stepper on a vertical axis (doc/model.md sections 7 and 18).

Disabled (a latched drive fault: here an injected one) the driver's bridge is
off and the windings open: the currents fall to 0 and the rotor feels only
its detent torque T_d sin(4 theta_e) and its damping. Oracle (section 2, at
rest): the load back-drives the screw with the torque T_L = W r_m (tan(lambda)
- mu'_s) / (1 + mu'_s tan(lambda)) through the static thread friction; the
axis holds if T_L <= 0 (self-locking) or T_L < T_d (the detent holds it), and
falls if T_L > T_d.
"""
import math

import numpy as np
import pytest

from leadscrew_sim import LeadScrewModel, load_preset
from stepper_axes import position_rows


def back_driving_torque(p):
    """Return T_L [N m]: the torque the static load puts on the screw through the thread."""
    w = (p.nut_mass + p.payload_mass) * p.gravity * math.sin(p.inclination)
    mu = p.mu_s * p.thread_factor
    t = math.tan(p.lead_angle)
    return w * p.r_m * (t - mu) / (1.0 + mu * t)


def disable_after_hold(p, seconds, dt=1e-3):
    """Hold 0.3 s, then latch a fault (windings open) and run ``seconds``; return the arrays."""
    m = LeadScrewModel(p, dt=dt)
    th0 = m.output().motor_angle
    m.run(None, commands=position_rows(300, th0))
    assert m.stepper_status()['enabled']
    m.inject_fault()
    n = int(round(seconds / dt))
    r = m.run(None, commands=position_rows(n, th0))
    return m, r


def test_disabled_self_locking_axis_holds():
    """nema23_tr12x3 (self-locking, 10 kg) with open windings: the nut moves < 1 um in 10 s."""
    p = load_preset('nema23_tr12x3')
    assert back_driving_torque(p) < 0.0 and p.self_locking
    m, r = disable_after_hold(p, 10.0)
    status = m.stepper_status()
    assert not status['enabled'] and status['current_set'] == 0.0
    assert np.all(r['phase_current_a'][5:] == 0.0) and np.all(r['phase_current_b'][5:] == 0.0)
    x = r['nut_position']
    print(f'self-locking, disabled: nut moved {1e9 * np.ptp(x):.1f} nm in 10 s')
    assert np.ptp(x) < 1e-6
    assert r['stuck'][-1]


@pytest.mark.parametrize('payload, falls', [(5.0, True), (2.0, False)])
def test_disabled_back_drivable_axis_falls_past_the_detent(payload, falls):
    """nema17_tr8x8 with open windings falls when T_L > T_d, and the detent holds it below."""
    p = load_preset('nema17_tr8x8', payload_mass=payload)
    t_l = back_driving_torque(p)
    assert (t_l > p.detent_torque) == falls, t_l
    m, r = disable_after_hold(p, 0.25)
    x = r['nut_position']
    print(f'payload {payload} kg: T_L {t_l:.4f} N m against T_d {p.detent_torque} N m; '
          f'the nut moved {1e3 * (x[-1] - x[0]):.3f} mm in 0.25 s')
    if falls:
        assert x[-1] - x[0] < -0.01          # more than 10 mm down
        assert r['nut_velocity'][-1] < -0.01
    else:
        # within the detent's well: less than a full step's travel, and at rest
        assert abs(x[-1] - x[0]) < p.lead_ratio * p.step_angle
        assert abs(r['nut_velocity'][-1]) < 1e-6


def test_enabled_again_the_rotor_snaps_a_whole_cycle():
    """Cleared, the driver holds its microstep: the fallen rotor rests 4 k full steps off it."""
    p = load_preset('nema17_tr8x8')
    m, r = disable_after_hold(p, 0.2)
    assert r['nut_position'][-1] < r['nut_position'][0] - 1e-3
    m.clear_fault()
    th = m.stepper_status()['step_position']
    r = m.run(None, commands=position_rows(1000, th))
    off = (r['step_position'][-1] - r['motor_angle'][-1]) / p.step_angle
    assert abs(r['motor_velocity'][-1]) < 1e-6
    assert abs(off - 4.0 * round(off / 4.0)) < 0.25, off
    assert m.stepper_status()['lost_full_steps'] == 4 * round(off / 4.0) != 0
