"""
The linearisation of steady sliding and its eigenvalues (physics.md section 12).

Coordinates (q sense, perturbations about :func:`.operating_point.operating_point`):
y = [q_m, q, x] with a compliant coupling under the velocity drive, [q, x]
with a rigid coupling (motor and screw one body) or a compliant one under the
ideal drive (q_m prescribed), [x] for the ideal drive with a rigid coupling
(the screw then prescribed). The contact stays on the loaded flank:
dN = -(k d(delta) + c d(delta)') / cos(lambda); friction
dF_f = -s (mu'0 sigma dN + |N0| (dmu'/dv) dv_s); the collar torque follows
|F_a|, the guide and bearing Coulomb terms are constant while sliding.

The velocity drive is treated as a continuous PI loop (its sampling at the
drive period and the sensors' difference quotients are left out; the drive
rate is far above the modes this analysis resolves): T_u = K_v (w_ref - w_fb)
+ (K_v / T_i) I, I' = w_ref - w_fb, with w_fb the motor rate through the
optional first-order velocity filter and the optional torque lag tau_e. Under
the velocity drive the chain has a translation mode (every angle and the nut
shifted by the rigid kinematics changes no force): it is removed exactly by
taking the quotient of the state space by it, so it never shows as a zero
eigenvalue.
"""
import math

import numpy as np

__all__ = ['eigenvalues', 'state_matrix']


def _coordinates(op, params):
    """Return (names, index of q_m or None, index of q or None, index of x)."""
    names = []
    if op['drive'] == 'velocity' and not op['rigid']:
        names.append('q_m')
    if op['drive'] == 'velocity' or not op['rigid']:
        names.append('q')
    names.append('x')
    idx = {n: i for i, n in enumerate(names)}
    return names, idx.get('q_m'), idx.get('q'), idx['x']


def _mechanics(op, params, slope):
    """Return (M, K, C, iq_m, iq, ix): M y'' + C y' + K y = (torque input), drive aside."""
    p = params
    names, im, iq, ix = _coordinates(op, params)
    n = len(names)
    lam = p.lead_angle
    sl, cl = math.sin(lam), math.cos(lam)
    rt, rm = p.lead_ratio, p.r_m
    s, sigma, n_abs = op['s'], op['sigma'], abs(op['N0'])
    # gradients over z = [y, y'] (length 2n)
    g_delta = np.zeros(2 * n)
    g_delta[ix] = 1.0
    g_delta[n + ix] = 0.0
    if iq is not None:
        g_delta[iq] = -rt
    g_ddelta = np.roll(g_delta, n)          # d(delta)' has the same weights on y'
    g_n = -(p.contact_stiffness * g_delta + p.contact_damping * g_ddelta) / cl
    g_vs = np.zeros(2 * n)
    g_vs[n + ix] = sl
    if iq is not None:
        g_vs[n + iq] = rm * cl
    g_f = -s * (op['mu0'] * sigma * g_n + n_abs * slope * g_vs)
    g_fa = cl * g_n + sl * g_f
    f = np.zeros((n, 2 * n))                # generalised forces, linear in z
    f[ix] = g_fa
    f[ix, n + ix] -= p.guide_viscous
    mass = np.zeros(n)
    mass[ix] = p.nut_mass + p.payload_mass
    if iq is not None:
        f[iq] = rm * (-sl * g_n + cl * g_f)
        f[iq] -= p.collar_mu * p.collar_radius * s * math.copysign(1.0, op['Fa0']) * g_fa
        f[iq, n + iq] -= p.bearing_viscous
        mass[iq] = p.screw_inertia + (p.motor_inertia if op['rigid'] else 0.0)
        if not op['rigid']:
            kc, cc = p.coupling_stiffness, p.coupling_damping
            f[iq, iq] -= kc
            f[iq, n + iq] -= cc
            if im is not None:
                f[iq, im] += kc
                f[iq, n + im] += cc
                f[im, im] -= kc
                f[im, iq] += kc
                f[im, n + im] -= cc
                f[im, n + iq] += cc
                mass[im] = p.motor_inertia
    return mass, f, im, iq, ix


def state_matrix(op, params, slope=None):
    """
    Return (A, translation): the first-order matrix X' = A X and the translation mode.

    X = [y, y', drive states (I if T_i > 0, w_f if a velocity filter, T_e if
    a torque lag)]; translation is the state of the rigid shift (None under
    the ideal drive, which has none).

    Parameters
    ----------
    op : dict
        The operating point.
    params : ScrewParams
        The axis.
    slope : float, optional
        dmu'/dv [s/m] to use; default the operating point's.

    """
    p = params
    slope = op['slope'] if slope is None else slope
    mass, f, im, iq, ix = _mechanics(op, params, slope)
    n = len(mass)
    velocity = op['drive'] == 'velocity'
    extra = []
    if velocity:
        if p.velocity_integral_time > 0.0:
            extra.append('I')
        if p.velocity_filter_time > 0.0:
            extra.append('w_f')
        if p.torque_lag > 0.0:
            extra.append('T_e')
    nx = 2 * n + len(extra)
    a = np.zeros((nx, nx))
    a[:n, n:2 * n] = np.eye(n)
    a[n:2 * n, :2 * n] = f / mass[:, None]
    translation = None
    if velocity:
        jm = im if im is not None else iq
        ex = {name: 2 * n + i for i, name in enumerate(extra)}
        w_fb = np.zeros(nx)                 # the drive's velocity feedback
        if 'w_f' in ex:
            w_fb[ex['w_f']] = 1.0
            tf = p.velocity_filter_time
            a[ex['w_f'], n + jm] += 1.0 / tf
            a[ex['w_f'], ex['w_f']] -= 1.0 / tf
        else:
            w_fb[n + jm] = 1.0
        t_u = -p.velocity_gain * w_fb
        if 'I' in ex:
            t_u[ex['I']] += p.velocity_gain / p.velocity_integral_time
            a[ex['I']] -= w_fb
        if 'T_e' in ex:
            a[ex['T_e']] += t_u / p.torque_lag
            a[ex['T_e'], ex['T_e']] -= 1.0 / p.torque_lag
            a[n + jm, ex['T_e']] += 1.0 / mass[jm]
        else:
            a[n + jm] += t_u / mass[jm]
        translation = np.zeros(nx)
        translation[ix] = p.lead_ratio
        translation[iq] = 1.0
        if im is not None:
            translation[im] = 1.0
    return a, translation


def eigenvalues(op, params, slope=None):
    """
    Return the eigenvalues [1/s] of the linearisation, the translation mode removed.

    Parameters
    ----------
    op : dict
        The operating point.
    params : ScrewParams
        The axis.
    slope : float, optional
        dmu'/dv [s/m] to use; default the operating point's.

    """
    a, e = state_matrix(op, params, slope)
    if e is not None:                        # the map A induces on X / span(e)
        j = int(np.argmax(np.abs(e)))
        keep = [i for i in range(len(e)) if i != j]
        a = a[np.ix_(keep, keep)] - np.outer(e[keep] / e[j], a[j, keep])
    return np.linalg.eigvals(a)
