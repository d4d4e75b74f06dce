"""
Thread geometry and quasi-static closed forms (doc/model.md sections 2 and 7).

All lengths in m, angles in rad, torques in N m, forces in N.
"""
import math

#: Thread half-angle in the axial section [rad], by thread form.
THREAD_HALF_ANGLES = {
    'square': 0.0,
    'acme': math.radians(14.5),
    'stub_acme': math.radians(14.5),
    'trapezoidal': math.radians(15.0),
}


def lead(pitch, starts):
    """Lead l = n_s p [m]."""
    return starts * pitch


def pitch_diameter(major_diameter, pitch):
    """Mean (pitch) diameter d_m = D - p/2 [m] (seed eq. 2.5)."""
    return major_diameter - pitch / 2.0


def lead_angle(lead_m, d_m):
    """Lead (helix) angle lambda [rad]: tan(lambda) = l / (pi d_m)."""
    return math.atan2(lead_m, math.pi * d_m)


def normal_half_angle(psi_a, lam):
    """Thread half-angle normal to the helix psi_n [rad]."""
    return math.atan(math.tan(psi_a) * math.cos(lam))


def raise_torque(load, r_m, mu_app, lam, collar_mu=0.0, collar_radius=0.0):
    """Torque to drive against an axial load W [N m] (thread plus collar)."""
    t = math.tan(lam)
    return load * r_m * (mu_app + t) / (1.0 - mu_app * t) + collar_mu * load * collar_radius


def lower_torque(load, r_m, mu_app, lam, collar_mu=0.0, collar_radius=0.0):
    """
    Torque to drive with an axial load W [N m]; <= 0 means it back-drives.

    The collar term is added as in Shigley eq. 8-6; it only applies while the
    thread term is positive (the collar then opposes the driven rotation).
    """
    t = math.tan(lam)
    return load * r_m * (mu_app - t) / (1.0 + mu_app * t) + collar_mu * load * collar_radius


def efficiency(mu_app, lam):
    """Return eta, the forward efficiency from torque to force."""
    t = math.tan(lam)
    return t * (1.0 - mu_app * t) / (t + mu_app)


def backdrive_efficiency(mu_app, lam):
    """Back-driving efficiency (force -> torque); <= 0 means self-locking."""
    t = math.tan(lam)
    return (t - mu_app) / (t * (1.0 + mu_app * t))


def is_self_locking(mu_s_app, lam):
    """Self-locking test: mu'_s >= tan(lambda)."""
    return mu_s_app >= math.tan(lam)
