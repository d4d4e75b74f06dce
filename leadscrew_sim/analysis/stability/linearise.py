"""
The linearisation of steady sliding and its eigenvalues (doc/stability.md).

Coordinates (q sense, perturbations about :func:`.operating_point.operating_point`):
y = [q_m, q, x] with a compliant coupling under the velocity drive, [q, x]
with a rigid coupling (motor and screw one body) or a compliant one under the
ideal drive (q_m prescribed), [x] for the ideal drive with a rigid coupling
(the screw then prescribed); a split nut adds half-nut B's x_b, joined to x
by the preload spring k_p, each half on its own loaded flank. The contact
stays on the loaded flank:
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
from dataclasses import dataclass
import math

import numpy as np

__all__ = ['Bodies', 'eigenvalues', 'mechanics', 'state_matrix']


@dataclass(frozen=True)
class Bodies:
    """
    Where each body sits in y, and the threads' axial force.

    Attributes
    ----------
    q_m, q : int or None
        Index of the motor angle, the screw angle [rad] (None: not a state).
    nuts : tuple of int
        Indices of nut A's x [m] and, with a split nut, half-nut B's x_b [m].
    thread_force : numpy.ndarray (2 n,)
        The axial force of the screw's thread(s) on the nut bodies [N] as a
        row over z = [y, y'] (both halves summed).

    """

    q_m: int
    q: int
    nuts: tuple
    thread_force: np.ndarray


def _coordinates(op, params):
    """Return (names, index of q_m or None, index of q or None, indices of the nut bodies)."""
    names = []
    if op['drive'] == 'velocity' and not op['rigid']:
        names.append('q_m')
    if op['drive'] == 'velocity' or not op['rigid']:
        names.append('q')
    names.append('x')
    if params.anti_backlash:
        names.append('x_b')
    idx = {n: i for i, n in enumerate(names)}
    return names, idx.get('q_m'), idx.get('q'), [idx[n] for n in ('x', 'x_b') if n in idx]


def _thread(op, p, iq, ix, n, n_abs, sigma, slope):
    """Return the gradients over z = [y, y'] of (N, F_f) of one nut body's thread."""
    lam = p.lead_angle
    sl, cl = math.sin(lam), math.cos(lam)
    g_delta = np.zeros(2 * n)
    g_delta[ix] = 1.0
    if iq is not None:
        g_delta[iq] = -p.lead_ratio
    g_ddelta = np.roll(g_delta, n)          # d(delta)' has the same weights on y'
    g_n = -(p.contact_stiffness * g_delta + p.contact_damping * g_ddelta) / cl
    g_vs = np.zeros(2 * n)
    g_vs[n + ix] = sl
    if iq is not None:
        g_vs[n + iq] = p.r_m * cl
    return g_n, -op['s'] * (op['mu0'] * sigma * g_n + n_abs * slope * g_vs)


def mechanics(op, params, slope=None):
    """
    Return (masses, F, bodies): M y'' = F z, z = [y, y'], the drive aside.

    The coordinates y follow ``op['drive']`` (see the module doc); M is
    diagonal (``masses`` [kg or kg m^2]), F the generalised forces [N or N m]
    linear in z, :class:`Bodies` the indices and the threads' axial force.

    Parameters
    ----------
    op : dict
        The operating point (:func:`.operating_point.operating_point`, or any
        dict with its keys drive, rigid, s, mu0, slope, Fa0 and nuts).
    params : ScrewParams
        The axis.
    slope : float, optional
        dmu'/dv [s/m] to use; default the operating point's.

    """
    p = params
    slope = op['slope'] if slope is None else slope
    names, im, iq, nuts = _coordinates(op, params)
    n = len(names)
    lam = p.lead_angle
    sl, cl = math.sin(lam), math.cos(lam)
    f = np.zeros((n, 2 * n))                # generalised forces, linear in z
    mass = np.zeros(n)
    g_fa = np.zeros(2 * n)                  # the axial force of both threads
    for ix, (sigma, n_abs), m in zip(nuts, op['nuts'],
                                     (p.nut_mass + p.payload_mass, p.second_nut_mass)):
        g_n, g_f = _thread(op, p, iq, ix, n, n_abs, sigma, slope)
        f[ix] += cl * g_n + sl * g_f
        g_fa += cl * g_n + sl * g_f
        mass[ix] = m
        if iq is not None:
            f[iq] += p.r_m * (-sl * g_n + cl * g_f)
    f[nuts[0], n + nuts[0]] -= p.guide_viscous
    if len(nuts) == 2:                      # preload spring: F_s on B, -F_s on A
        g_s = np.zeros(2 * n)
        g_s[nuts[1]], g_s[nuts[0]] = -p.preload_stiffness, p.preload_stiffness
        f[nuts[1]] += g_s
        f[nuts[0]] -= g_s
    if iq is not None:
        f[iq] -= p.collar_mu * p.collar_radius * op['s'] * math.copysign(1.0, op['Fa0']) * g_fa
        f[iq, n + iq] -= p.bearing_viscous
        mass[iq] = p.screw_inertia + (p.motor_inertia if op['rigid'] else 0.0)
        if not op['rigid']:
            _coupling(f, mass, p, im, iq, n)
    return mass, f, Bodies(im, iq, tuple(nuts), g_fa)


def _coupling(f, mass, p, im, iq, n):
    """Add the compliant coupling's forces (and the rotor's inertia, when a state) in place."""
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
    mass, f, bodies = mechanics(op, params, slope)
    im, iq, nuts = bodies.q_m, bodies.q, list(bodies.nuts)
    n = len(mass)
    stepper = op.get('stepper')
    velocity = op['drive'] == 'velocity' and stepper is None
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
    if stepper is not None:        # the rotor on the magnetic spring k_e, its damping B
        jm = im if im is not None else iq
        a[n + jm, jm] -= stepper[0] / mass[jm]
        a[n + jm, n + jm] -= stepper[1] / mass[jm]
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
        translation[nuts] = p.lead_ratio
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
