"""
Linear stability of steady sliding against oracles derived here (doc/model.md, doc/stability.md).

Each oracle is written from the equations in this file: the rigid 1-DOF
threshold, a screw + nut eigen-analysis with a compliant contact, the
effective inertia J_e and the flutter onset of a two-DOF undamped model.
"""
import math

import numpy as np
import pytest
from scipy.optimize import brentq

from leadscrew_sim.analysis.stability import linear_stability
from leadscrew_sim.core.params import ScrewParams

PSI_A = math.radians(15.0)      # trapezoidal thread half-angle


def geometry(p):
    """Return (r_m, r_t, lambda, thread factor 1 / cos(psi_n)) from D, p, n_s."""
    lead = p.pitch * p.starts
    rm = (p.major_diameter - p.pitch / 2.0) / 2.0
    lam = math.atan(lead / (2.0 * math.pi * rm))
    psi_n = math.atan(math.tan(PSI_A) * math.cos(lam))
    return rm, lead / (2.0 * math.pi), lam, 1.0 / math.cos(psi_n)


def apparent_mu(p, vs):
    """Return (mu', dmu'/dv) of the Stribeck law at the sliding speed vs > 0."""
    _, _, _, tf = geometry(p)
    z = vs / p.stribeck_velocity
    e = math.exp(-z)       # exponent 1 in these tests
    mu = tf * (p.mu_k + (p.mu_s - p.mu_k) * e + p.mu_viscous * vs)
    return mu, tf * (p.mu_viscous - (p.mu_s - p.mu_k) * e / p.stribeck_velocity)


def raising_axis(**kw):
    """Return a vertical axis raised by an ideal drive through a damped compliant coupling."""
    base = dict(mu_s=0.15, mu_k=0.15, mu_viscous=0.0, coupling_stiffness=2.0,
                coupling_damping=2e-4, bearing_viscous=1e-4, guide_viscous=5.0,
                contact_stiffness=1e9, contact_damping=1e3, payload_mass=20.0,
                screw_inertia=8e-6)
    base.update(kw)
    return ScrewParams(**base)


def own_eigs(p, v):
    """
    Eigenvalues of the screw (q) + nut (x) model raised at v > 0 on the leading flank.

    Ideal drive: q_m fixed in the perturbation; the coupling k_c, c_c ties q to it.
    """
    rm, rt, lam, _ = geometry(p)
    sl, cl = math.sin(lam), math.cos(lam)
    mu, slope = apparent_mu(p, v / sl)
    m = p.nut_mass + p.payload_mass
    w = m * p.gravity + p.guide_viscous * v
    n0 = w / (cl - mu * sl)
    k, c = p.contact_stiffness, p.contact_damping
    # dN = -(k (x - rt q) + c (x' - rt q')) / cl;  dF = -(mu dN + n0 slope (rm cl q' + sl x'))
    # nut:   m x'' = cl dN + sl dF - c_x x'
    # screw: J q'' = rm (-sl dN + cl dF) - k_c q - (c_c + c_s) q'
    fn = cl - sl * mu             # d(axial force)/dN
    tn = rm * (-sl - cl * mu)     # d(torque)/dN
    kx = np.array([-rt, 1.0]) * (-k / cl)     # dN over [q, x]
    cx = np.array([-rt, 1.0]) * (-c / cl)     # dN over [q', x']
    vsg = np.array([rm * cl, sl]) * (-n0 * slope)
    stiff = np.array([tn * kx - np.array([p.coupling_stiffness, 0.0]), fn * kx])
    damp = np.array([tn * cx + rm * cl * vsg
                     - np.array([p.coupling_damping + p.bearing_viscous, 0.0]),
                     fn * cx + sl * vsg - np.array([0.0, p.guide_viscous])])
    minv = np.diag([1.0 / p.screw_inertia, 1.0 / m])
    a = np.block([[np.zeros((2, 2)), np.eye(2)], [minv @ stiff, minv @ damp]])
    return np.linalg.eigvals(a)


def own_growth(p, v):
    """Return the least stable eigenvalue of own_eigs."""
    e = own_eigs(p, v)
    return e[np.argmax(e.real)]


def rigid_threshold_slope(p, v):
    """Return the dmu'/dv at which the rigid 1-DOF coupling mode is neutral (section 9)."""
    rm, rt, lam, _ = geometry(p)
    sl, cl, tl = math.sin(lam), math.cos(lam), math.tan(lam)
    mu, _ = apparent_mu(p, v / sl)
    g = (tl + mu) / (1.0 - mu * tl)
    w = (p.nut_mass + p.payload_mass) * p.gravity + p.guide_viscous * v
    c_sum = p.bearing_viscous + p.coupling_damping + p.guide_viscous * rm * rt * g
    return -c_sum * cl ** 3 * (1.0 - mu * tl) ** 2 / (rm * rm * w)


def bisect(f, lo, hi, tol=1e-10):
    """Return the sign change of f in [lo, hi] (f(lo) < 0 < f(hi) or the reverse)."""
    return brentq(f, lo, hi, xtol=tol * max(abs(lo), abs(hi)), rtol=1e-12)


def test_negative_damping_along_mu_viscous():
    """The boundary along mu_viscous: rigid formula, own 2-DOF and ours agree."""
    v = 2e-3
    _, _, _, tf = geometry(raising_axis())
    rigid = rigid_threshold_slope(raising_axis(), v) / tf

    def ours(mv):
        return linear_stability(raising_axis(mu_viscous=mv), v, 'ideal')['growth_rate']

    def own(mv):
        return own_growth(raising_axis(mu_viscous=mv), v).real

    lo, hi = 3.0 * rigid, 0.3 * rigid
    b_own = bisect(own, lo, hi)
    b_ours = bisect(ours, lo, hi)
    assert abs(b_own - rigid) < 0.05 * abs(rigid)      # the compliance correction is small
    assert abs(b_ours - b_own) < 0.01 * abs(b_own)
    for mv in (1.5 * b_own, 1.1 * b_own, 0.9 * b_own, 0.5 * b_own):
        row = linear_stability(raising_axis(mu_viscous=mv), v, 'ideal')
        lam = own_growth(raising_axis(mu_viscous=mv), v)
        assert row['growth_rate'] == pytest.approx(lam.real, rel=0.01)
        assert row['frequency'] == pytest.approx(abs(lam.imag) / (2 * math.pi), rel=0.01)
        assert row['mechanism'] == ('negative_damping' if mv < b_own else 'stable')


def test_negative_damping_along_speed_stribeck():
    """The boundary speed of a Stribeck drop: ours vs the own eigen-analysis."""
    base = dict(mu_s=0.3, mu_k=0.15, stribeck_velocity=1e-3)

    def ours(v):
        return linear_stability(raising_axis(**base), v, 'ideal')['growth_rate']

    def own(v):
        return own_growth(raising_axis(**base), v).real

    lo, hi = 2e-5, 2e-3
    assert own(lo) > 0.0 > own(hi)
    b_own = bisect(own, lo, hi)
    b_ours = bisect(ours, lo, hi)
    assert abs(b_ours - b_own) < 0.01 * b_own
    for v in (0.5 * b_own, 0.9 * b_own, 1.1 * b_own, 2.0 * b_own):
        row = linear_stability(raising_axis(**base), v, 'ideal')
        lam = own_growth(raising_axis(**base), v)
        assert row['growth_rate'] == pytest.approx(lam.real, rel=0.01)
        assert row['frequency'] == pytest.approx(abs(lam.imag) / (2 * math.pi), rel=0.01)


def own_effective_inertia(p, v, rigid):
    """J_e = J_s (+ J_m) + m r_m r_t G, G for the direction relative to the load."""
    rm, rt, lam, _ = geometry(p)
    tl = math.tan(lam)
    mu, _ = apparent_mu(p, abs(v) / math.sin(lam))
    g = (tl + mu) / (1 - mu * tl) if v > 0 else -(mu - tl) / (1 + mu * tl)
    return (p.screw_inertia + (p.motor_inertia if rigid else 0.0)
            + (p.nut_mass + p.payload_mass) * rm * rt * g)


@pytest.mark.parametrize('kc', [0.0, 2.0])
@pytest.mark.parametrize('drive', ['ideal', 'velocity'])
def test_kinematic_constraint(kc, drive):
    """A self-locking screw lowered with a heavy load: J_e <= 0 reported and classified."""
    p = ScrewParams(mu_s=0.3, mu_k=0.3, coupling_stiffness=kc, payload_mass=200.0,
                    screw_inertia=2e-6, motor_inertia=1e-5, contact_stiffness=1e8,
                    velocity_gain=0.02, max_torque=50.0)
    for v in (-1e-3, 1e-3):
        row = linear_stability(p, v, drive)
        j_e = own_effective_inertia(p, v, kc == 0.0)
        assert row['effective_inertia'] == pytest.approx(j_e, rel=1e-9)
        if v < 0:
            assert j_e <= 0.0 and row['mechanism'] == 'kinematic_constraint'
        else:
            assert j_e > 0.0 and row['mechanism'] != 'kinematic_constraint'


def coupling_axis(mu):
    """Return an axis lowering a light nut on a soft contact, no damping, no friction slope."""
    return ScrewParams(mu_s=mu, mu_k=mu, contact_stiffness=1e6, contact_damping=0.0,
                       coupling_stiffness=2.0, bearing_viscous=0.0, guide_viscous=0.0,
                       payload_mass=1.0, screw_inertia=2e-6)


def own_flutter_discriminant(mu_app, p):
    """
    Discriminant of det(K - w^2 M) = 0 for screw q on the coupling, nut x on the contact.

    Lowering (s = -1) on the leading flank, slope 0: dF = mu' dN,
    dN = -k (x - r_t q) / cos; m x'' = (cos + mu' sin) dN,
    J q'' = r_m (mu' cos - sin) dN - k_c q. Negative: w^2 complex (flutter).
    """
    rm, rt, lam, _ = geometry(p)
    tl = math.tan(lam)
    m, j, k, kc = p.nut_mass + p.payload_mass, p.screw_inertia, p.contact_stiffness, 2.0
    a1 = k * (1 + mu_app * tl)
    a2 = rm * k * (mu_app - tl)
    b = a1 * j + m * kc - m * a2 * rt
    return b * b - 4 * m * j * a1 * kc


def test_mode_coupling_onset():
    """The flutter onset friction coefficient: ours vs the own two-DOF derivation."""
    p0 = coupling_axis(0.1)
    _, _, lam, tf = geometry(p0)
    mu_own = brentq(lambda mu: own_flutter_discriminant(mu * tf, p0), 0.05, 0.5, xtol=1e-12)

    def ours(mu):
        row = linear_stability(coupling_axis(mu), -1e-3, 'ideal')
        return row['growth_rate'] - 1e-7 * 2 * math.pi * row['frequency']

    mu_ours = brentq(ours, 0.05, 0.5, xtol=1e-10)
    assert mu_ours == pytest.approx(mu_own, rel=0.01)
    assert mu_own * tf > math.tan(lam)
    row = linear_stability(coupling_axis(1.2 * mu_own), -1e-3, 'ideal')
    assert row['mechanism'] == 'mode_coupling' and row['effective_inertia'] > 0.0
    assert linear_stability(coupling_axis(0.8 * mu_own), -1e-3, 'ideal')['mechanism'] == 'stable'


def test_refusals():
    """A zero speed and an unknown drive are refused with the parameter named."""
    p = ScrewParams()
    with pytest.raises(ValueError, match='speed'):
        linear_stability(p, 0.0)
    with pytest.raises(ValueError, match='drive'):
        linear_stability(p, 1e-3, 'torque')


def test_velocity_loop_threshold_rigid_coupling():
    """
    Velocity drive, rigid coupling: the 1-DOF threshold with the loop's damping K_v.

    With the continuous PI loop on the rigid axis, J_e q'' + (c_s + K_v +
    c_x r_m r_t G + c_f) q' + (K_v / T_i) q = 0: neutral where the damping sum
    is 0 (the integral adds stiffness only). The stiff contact shifts it by
    far less than 1 %.
    """
    v = 2e-3

    def axis(mv):
        return raising_axis(mu_viscous=mv, coupling_stiffness=0.0, coupling_damping=0.0,
                            contact_stiffness=1e10, velocity_gain=3.85e-3,
                            velocity_integral_time=0.0127)

    p = axis(0.0)
    rm, rt, lam, tf = geometry(p)
    sl, cl, tl = math.sin(lam), math.cos(lam), math.tan(lam)
    mu, _ = apparent_mu(p, v / sl)
    g = (tl + mu) / (1.0 - mu * tl)
    w = (p.nut_mass + p.payload_mass) * p.gravity + p.guide_viscous * v
    c_sum = p.bearing_viscous + p.velocity_gain + p.guide_viscous * rm * rt * g
    slope = -c_sum * cl ** 3 * (1.0 - mu * tl) ** 2 / (rm * rm * w)
    rigid = slope / tf
    b_ours = bisect(lambda mv: linear_stability(axis(mv), v, 'velocity')['growth_rate'],
                    3.0 * rigid, 0.3 * rigid)
    assert abs(b_ours - rigid) < 0.01 * abs(rigid), (b_ours, rigid)
    assert linear_stability(axis(1.2 * rigid), v)['mechanism'] == 'negative_damping'
    assert linear_stability(axis(0.8 * rigid), v)['mechanism'] == 'stable'
