"""
Stability of the shipped presets and of the split nut, against eigen-analyses written here.

The oracles follow the equations of doc/model.md (thread contact, Stribeck
friction, coupling, the servo's PI velocity loop, the preload spring of the
split nut) linearised about steady sliding, in the test's own coordinates.
"""
import dataclasses
import math

import numpy as np
import pytest
from scipy.optimize import brentq

from leadscrew_sim import load_preset, preset_names
from leadscrew_sim.analysis.stability import linear_stability, nonlinear_stability
from leadscrew_sim.analysis.stability.linearise import eigenvalues
from leadscrew_sim.analysis.stability.operating_point import operating_point
from leadscrew_sim.core.params import ScrewParams

from test_stability_linear import apparent_mu as friction, geometry   # noqa: I100


def steady_nuts(p, v):
    """
    Return [(sigma, |N|), ...] of the nut bodies raised at v > 0 (fixed-point on the preload).

    Nut A's thread carries W = m g + c_x v (+ F_s), half-nut B's m_b g - F_s,
    F_s = F_p + k_p (b - (delta_B - delta_A)), delta = -sigma (b/2 + |N| cos / k).
    """
    rm, rt, lam, _ = geometry(p)
    sl, cl = math.sin(lam), math.cos(lam)
    mu, _ = friction(p, v / sl)
    w_a = (p.nut_mass + p.payload_mass) * p.gravity * math.sin(p.inclination) \
        + p.guide_viscous * v

    def nut(w):
        sg = 1.0 if w > 0 else -1.0
        return sg, abs(w) / (cl - sg * mu * sl)
    if not p.anti_backlash:
        return [nut(w_a)]
    w_b = p.second_nut_mass * p.gravity * math.sin(p.inclination)
    f_s = p.preload_force
    for _ in range(200):
        (sa, na), (sb, nb) = nut(w_a + f_s), nut(w_b - f_s)
        d_a = -sa * (p.backlash / 2 + na * cl / p.contact_stiffness)
        d_b = -sb * (p.backlash / 2 + nb * cl / p.contact_stiffness)
        f_s = p.preload_force + p.preload_stiffness * (p.backlash - (d_b - d_a))
    return [nut(w_a + f_s), nut(w_b - f_s)]


def own_stepper_stiffness(p, v):
    """
    Return the magnetic stiffness N_r T_h cos(N_r phi) [N m/rad] of a stepper raising at v.

    The rotor lags the commanded angle by phi: T_h sin(N_r phi) is the thread's
    torque r_m (sin + mu' cos) N per nut body plus the bearing's and the rotor's
    viscous torques (no collar, no Coulomb bearing or guide terms here).
    """
    rm, rt, lam, _ = geometry(p)
    sl, cl = math.sin(lam), math.cos(lam)
    mu, _ = friction(p, v / sl)
    omega = v / rt
    torque = sum(rm * (sg * sl + mu * cl) * nn for sg, nn in steady_nuts(p, v)) \
        + (p.bearing_viscous + p.rotor_damping) * omega
    nr = math.pi / (2.0 * p.step_angle)
    return nr * p.holding_torque * math.cos(math.asin(torque / p.holding_torque))


def own_matrix(p, v, drive):
    """
    First-order matrix of the axis raised at v > 0: q_m (velocity drive), q, x_A (, x_B).

    Velocity drive: T = -K_v q_m' - (K_v / T_i) q_m (the PI loop; its integral state
    is -q_m in the perturbation). Ideal drive: q_m = 0. Stepper (rigid coupling):
    T = -k_e q - B q' on the screw and rotor. The collar is frictionless.
    """
    if drive == 'stepper':
        return own_stepper_matrix(p, v)
    rm, rt, lam, _ = geometry(p)
    sl, cl = math.sin(lam), math.cos(lam)
    _, slope = friction(p, v / sl)
    nuts = steady_nuts(p, v)
    motor = drive == 'velocity'
    n = 1 + motor + len(nuts)
    iq, ix = int(motor), [1 + motor + i for i in range(len(nuts))]
    f = np.zeros((n, 2 * n))
    mass = np.zeros(n)
    for i, (sg, nn) in zip(ix, nuts):
        d = np.zeros(2 * n)
        d[i], d[iq] = 1.0, -rt
        dn = -(p.contact_stiffness * d + p.contact_damping * np.roll(d, n)) / cl
        vs = np.zeros(2 * n)
        vs[n + iq], vs[n + i] = rm * cl, sl
        df = -(friction(p, v / sl)[0] * sg * dn + nn * slope * vs)
        f[i] += cl * dn + sl * df
        f[iq] += rm * (-sl * dn + cl * df)
    mass[ix[0]] = p.nut_mass + p.payload_mass
    f[ix[0], n + ix[0]] -= p.guide_viscous
    if len(ix) == 2:
        mass[ix[1]] = p.second_nut_mass
        for a, b in ((ix[0], ix[1]), (ix[1], ix[0])):
            f[a, a] -= p.preload_stiffness
            f[a, b] += p.preload_stiffness
    mass[iq] = p.screw_inertia
    kc, cc = p.coupling_stiffness, p.coupling_damping
    f[iq, iq] -= kc
    f[iq, n + iq] -= cc + p.bearing_viscous
    if motor:
        mass[0] = p.motor_inertia
        f[iq, 0] += kc
        f[iq, n] += cc
        f[0, 0] -= kc + p.velocity_gain / p.velocity_integral_time
        f[0, iq] += kc
        f[0, n] -= cc + p.velocity_gain
        f[0, n + iq] += cc
    a = np.zeros((2 * n, 2 * n))
    a[:n, n:] = np.eye(n)
    a[n:] = f / mass[:, None]
    return a


def own_stepper_matrix(p, v):
    """
    First-order matrix [q, x_A, q', x_A'] of a stepper axis with a rigid coupling.

    Screw and rotor (J_s + J_m) are tied to the commanded angle by k_e and B:
    the ideal drive's compliant coupling with k_c = k_e, c_c = B.
    """
    assert p.coupling_stiffness == 0.0
    return own_matrix(dataclasses.replace(
        p, drive_type='servo', coupling_stiffness=own_stepper_stiffness(p, v),
        coupling_damping=p.rotor_damping, screw_inertia=p.screw_inertia + p.motor_inertia),
        v, 'ideal')


def own_growth(p, v, drive):
    """Return the eigenvalue of own_matrix with the largest real part."""
    e = np.linalg.eigvals(own_matrix(p, v, drive))
    return e[np.argmax(e.real)]


def test_stick_slip_preset_critical_speed_velocity_drive():
    """stick_slip under its servo: unstable below the own critical speed, stable above."""
    p = load_preset('stick_slip', collar_mu=0.0)
    assert p.velocity_filter_time == 0.0 and p.torque_lag == 0.0   # the oracle has neither
    v_own = brentq(lambda v: own_growth(p, v, 'velocity').real, 2e-4, 2e-3, xtol=1e-12)
    v_ours = brentq(lambda v: linear_stability(p, v, 'velocity')['growth_rate'],
                    2e-4, 2e-3, xtol=1e-12)
    assert v_ours == pytest.approx(v_own, rel=0.01)
    for v in (0.7 * v_own, 0.95 * v_own, 1.05 * v_own, 1.5 * v_own):
        row = linear_stability(p, v, 'velocity')
        lam = own_growth(p, v, 'velocity')
        assert row['growth_rate'] == pytest.approx(lam.real, rel=0.01)
        assert row['frequency'] == pytest.approx(abs(lam.imag) / (2 * math.pi), rel=0.01)
        assert row['mechanism'] == ('negative_damping' if v < v_own else 'stable')


def test_stick_slip_preset_nonlinear_either_side():
    """The full model sticks and slips at half the critical speed, slides steadily at twice."""
    p = load_preset('stick_slip')
    v_c = brentq(lambda v: linear_stability(p, v, 'velocity')['growth_rate'], 2e-4, 2e-3)
    below = nonlinear_stability(p, 0.5 * v_c, 'velocity', duration=2.0)
    above = nonlinear_stability(p, 2.0 * v_c, 'velocity', duration=2.0)
    assert below['verdict'] == 'limit_cycle' and below['stick_fraction'] > 0.0
    assert above['verdict'] == 'stable'


def split_axis(**kw):
    """Return a vertical axis with a preloaded split nut, raised through a compliant coupling."""
    base = dict(anti_backlash=True, preload_force=40.0, preload_stiffness=2e4,
                second_nut_mass=0.05, mu_s=0.3, mu_k=0.15, stribeck_velocity=1e-3,
                coupling_stiffness=2.0, coupling_damping=0.0, bearing_viscous=0.0,
                guide_viscous=0.0, collar_mu=0.0, payload_mass=5.0, inclination=math.pi / 2,
                contact_stiffness=1e8, contact_damping=5e3, screw_inertia=8e-6,
                motor_inertia=1e-5, max_torque=5.0)
    base.update(kw)
    return ScrewParams(**base)


@pytest.mark.parametrize('drive', ['ideal', 'velocity'])
def test_split_nut_threshold_and_modes(drive):
    """Split nut: the critical speed, growth rate and frequency of the own 3-4 DOF analysis."""
    p = split_axis(velocity_gain=0.005, velocity_integral_time=0.0127)
    nuts = steady_nuts(p, 1e-3)
    assert [sg for sg, _ in nuts] == [1.0, -1.0]        # A on its leading, B on its trailing flank
    row = linear_stability(p, 1e-3, drive)
    assert row['N0'] == pytest.approx(nuts[0][1], rel=1e-9)
    lo, hi = 1e-4, 5e-2
    assert own_growth(p, lo, drive).real > 0.0 > own_growth(p, hi, drive).real
    v_own = brentq(lambda v: own_growth(p, v, drive).real, lo, hi, xtol=1e-12)
    v_ours = brentq(lambda v: linear_stability(p, v, drive)['growth_rate'], lo, hi, xtol=1e-12)
    assert v_ours == pytest.approx(v_own, rel=0.01)
    for v in (0.5 * v_own, 0.9 * v_own, 1.1 * v_own, 2.0 * v_own):
        got, lam = linear_stability(p, v, drive), own_growth(p, v, drive)
        assert got['growth_rate'] == pytest.approx(lam.real, rel=0.01)
        assert got['frequency'] == pytest.approx(abs(lam.imag) / (2 * math.pi), rel=0.01)
    # every mode, half-nut B's on its contact and the preload spring included: both are
    # exact linearisations of the same equations, so they agree to round-off
    own = np.linalg.eigvals(own_matrix(p, 2e-3, drive))
    ours = eigenvalues(operating_point(p, 2e-3, drive), p)
    assert len(ours) == len(own)
    for lam in own:
        assert np.min(np.abs(ours - lam)) < 1e-6 * abs(lam)


@pytest.mark.parametrize('name', preset_names())
def test_every_preset_classified(name):
    """Each preset at +-1 mm/s under both drives gets a mechanism, linear and nonlinear."""
    p = load_preset(name)
    for v in (1e-3, -1e-3):
        for drive in ('velocity', 'ideal'):
            row = linear_stability(p, v, drive)
            assert row['mechanism'] in ('stable', 'negative_damping', 'mode_coupling',
                                        'kinematic_constraint')
            assert math.isfinite(row['growth_rate'])
    res = nonlinear_stability(p, 1e-3, 'velocity', duration=0.5)
    assert res['verdict'] in ('stable', 'limit_cycle', 'bistable')


def test_stepper_axis_modes_and_refusals():
    """A stepper holding the speed: the rotor on its magnetic spring; steps lost are refused."""
    p = load_preset('nema23_tr12x3', collar_mu=0.0)
    assert p.coupling_stiffness == 0.0 and p.bearing_coulomb == 0.0 and p.guide_coulomb == 0.0
    for v in (2e-4, 1e-3, 5e-3):
        own = np.linalg.eigvals(own_matrix(p, v, 'stepper'))
        ours = eigenvalues(operating_point(p, v, 'velocity'), p)
        assert len(ours) == len(own)
        for lam in own:            # the same equations: agreement to round-off
            assert np.min(np.abs(ours - lam)) < 1e-6 * abs(lam)
    # small-signal natural frequency sqrt(N_r T_h / J_total) when the load angle is small
    # (frictionless, horizontal, undamped rotor: the load angle is ~0; the stiff contact
    # moves the rigid-axis figure by far less than the 1 % allowed)
    light = dataclasses.replace(p, inclination=0.0, guide_viscous=1.0, mu_s=0.0, mu_k=0.0,
                                rotor_damping=0.0)
    j_total = p.motor_inertia + p.screw_inertia + (p.nut_mass + p.payload_mass) * (
        p.pitch / (2 * math.pi)) ** 2
    f_n = math.sqrt(50 * p.holding_torque / j_total) / (2 * math.pi)
    assert linear_stability(light, 1e-3, 'velocity')['frequency'] == pytest.approx(f_n, rel=0.01)
    with pytest.raises(ValueError, match='holding_torque'):
        linear_stability(dataclasses.replace(p, payload_mass=200.0), 1e-3, 'velocity')
    with pytest.raises(ValueError, match='max_step_rate'):
        linear_stability(p, 0.1, 'velocity')
