"""
The linearised axis without its drive: the plant of a frequency response (doc/stability.md).

The mechanics (masses, the thread's contact and friction, the coupling, the
preload spring of a split nut) are those of the stability analysis,
:func:`..stability.linearise.mechanics` (doc/stability.md), in its
coordinates with the motor free: y = [q_m, q, x(, x_b)] with a compliant
coupling, [q, x(, x_b)] with a rigid one. Operating points (q sense,
perturbations about them):

- sliding at a nut speed v != 0: the steady sliding state of the stability
  analysis (:func:`..stability.operating_point.operating_point`): each nut
  body on its loaded flank, friction linearised with its slope, the collar
  torque following |F_a|;
- at rest (v = 0) on the loaded flank: the contact is a spring; a split
  nut's halves sit on the flanks the preload spring and their loads pick
  (the frictionless balance). With thread friction (mu_s > 0) the thread is
  stuck, its stiction limit not reached: the sliding velocity
  v_s = r_m cos(lambda) q' + sin(lambda) x' of every nut body stays 0, so
  each moves with the screw as x = -r_m cot(lambda) q (the friction force is
  the constraint's reaction) and only the contacts' normal springs let the
  screw turn. The bearing, guide and collar Coulomb terms are left out at
  rest (stuck, they only add to the thread's lock). ``rest='free'`` leaves
  the thread's friction out instead: the axis a test large enough to break
  it loose sees (between its reversals).

:func:`plant` returns a :class:`Plant`: X' = A X + B_T T_c + B_F F with X the
coordinates, their rates and the motor torque lag state (when tau_e > 0);
T_c the torque command [N m], F the external force on nut A [N], both q
sense / +x; and rows that read the motor angle and rate, nut A's position and
velocity, the axial thread force (on both halves of a split nut) and the
applied motor torque.
"""
from dataclasses import dataclass
import math

import numpy as np

from ...core.params import ParameterError
from ..stability.linearise import mechanics
from ..stability.operating_point import split_nut, operating_point

__all__ = ['check_servo', 'Plant', 'plant', 'REST_STATES', 'rest_load', 'thread_state']

#: The thread at rest: stuck (stiction holds it), or free (friction left out).
REST_STATES = ('stuck', 'free')


@dataclass
class Plant:
    """
    The linear plant: X' = A X + B_T T_c + B_F F; rows over X (with coefficients on T_c, F).

    Attributes
    ----------
    a : ndarray (n, n)
        State matrix [SI].
    b_t, b_f : ndarray (n,)
        Inputs: torque command [N m] (q sense), external force [N] (+x).
    rows : dict
        name -> (row over X, coefficient on T_c, coefficient on F) for
        q_m [rad], w_m [rad/s] (motor, q sense), x [m], v [m/s], force [N]
        (axial thread force on the nut), torque [N m] (applied, q sense).
    lag : bool
        The applied torque is a state (tau_e > 0); else it is T_c itself.
    state : str
        'rest', 'stuck' (at rest, thread stuck) or 'sliding'.
    op : dict
        The operating point (speed [m/s], load [N], ...).

    """

    a: np.ndarray
    b_t: np.ndarray
    b_f: np.ndarray
    rows: dict
    lag: bool
    state: str
    op: dict


def rest_load(p):
    """Return W [N]: the axial force the thread supplies along +x at rest (-F_g - F_ext)."""
    f_g = -(p.nut_mass + p.payload_mass) * p.gravity * math.sin(p.inclination)
    return -f_g - p.external_force


def check_servo(params, what='the linear model'):
    """Refuse an axis whose motor is not the servo drive (``what`` names the refused figure)."""
    drive = getattr(params, 'drive_type', 'servo')
    if drive != 'servo':
        raise ParameterError('drive_type', f'{drive!r}: {what} of the frequency response '
                             "covers the servo drive ('servo') only; measure a stepper axis "
                             'with a simulated sine dwell of an input -> output response')


def thread_state(params, speed=0.0, rest='stuck'):
    """
    Return the thread's state in the linear model: 'sliding', 'stuck' or 'rest' (free at rest).

    Stuck: at rest (speed 0 [m/s]) with static friction (mu_s > 0) and ``rest`` 'stuck'.
    """
    if speed != 0.0:
        return 'sliding'
    if rest not in REST_STATES:
        raise ParameterError('rest', f'{rest!r} is not one of {", ".join(REST_STATES)}')
    return 'stuck' if params.mu_s > 0.0 and rest == 'stuck' else 'rest'


def _rest_op(p):
    """Return the operating point dict at rest (friction out), for stability's mechanics."""
    load = rest_load(p)
    if p.anti_backlash:
        nuts, _ = split_nut(p, load, 0.0, 0.0, 0.0)
    elif load == 0.0 and p.backlash > 0.0:
        raise ParameterError('backlash', f'{p.backlash!r} m with no axial load at rest: the nut '
                             'floats in the backlash (give a load, or backlash 0, or a speed)')
    else:
        nuts = ((1.0 if load >= 0.0 else -1.0, abs(load) / math.cos(p.lead_angle)),)
    return dict(speed=0.0, s=0.0, sigma=nuts[0][0], N0=0.0, mu0=0.0, slope=0.0, Fa0=0.0,
                load=load, torque=p.lead_ratio * load, rigid=p.coupling_stiffness == 0.0,
                drive='velocity', nuts=nuts)


def _stuck_map(p, n, iq, nuts):
    """Return R (n, n - nuts): y = R y_r with every nut body at x = -r_m cot(lambda) q (stuck)."""
    keep = [i for i in range(n) if i not in nuts]
    r = np.zeros((n, len(keep)))
    for j, i in enumerate(keep):
        r[i, j] = 1.0
    for ix in nuts:
        r[ix, keep.index(iq)] = -p.r_m / math.tan(p.lead_angle)
    return r


def _second_order(p, op, stuck):
    """Return (mass matrix, F over [y, y'], R, RR, bodies) of the mechanics."""
    mass, f, bodies = mechanics(op, p)
    n = len(mass)
    r = _stuck_map(p, n, bodies.q, bodies.nuts) if stuck else np.eye(n)
    rr = np.zeros((2 * n, 2 * r.shape[1]))
    rr[:n, :r.shape[1]] = r
    rr[n:, r.shape[1]:] = r
    return np.diag(mass), f, r, rr, bodies


def plant(params, speed=0.0, rest='stuck'):
    """
    Return the :class:`Plant` of the axis at rest (speed 0) or sliding at ``speed`` [m/s].

    Parameters
    ----------
    params : ScrewParams
        The axis (single or split nut).
    speed : float
        Nut speed [m/s]; 0: at rest on the loaded flank.
    rest : str
        At rest: 'stuck' (the thread held by stiction when mu_s > 0) or 'free'.

    Raises
    ------
    ParameterError
        For a stepper axis (the drive here is the servo's), a nut floating in
        the backlash at rest, or a sliding state that does not exist (see the
        stability analysis).

    """
    p = params
    check_servo(p)
    state = thread_state(p, speed, rest)
    if state == 'sliding':
        op = dict(operating_point(p, speed, 'ideal'), drive='velocity')
    else:
        op = _rest_op(p)
    stuck = state == 'stuck'
    m, f, r, rr, bodies = _second_order(p, op, stuck)
    im, iq, ix = bodies.q_m, bodies.q, bodies.nuts[0]
    n = len(m)
    nr = r.shape[1]
    m_r = r.T @ m @ r
    f_r = r.T @ f @ rr                      # generalised forces over [y_r, y_r']
    jm = im if im is not None else iq       # the body the motor torque drives
    lag = p.torque_lag > 0.0
    nx = 2 * nr + (1 if lag else 0)
    minv = np.linalg.inv(m_r)
    a = np.zeros((nx, nx))
    a[:nr, nr:2 * nr] = np.eye(nr)
    a[nr:2 * nr, :2 * nr] = minv @ f_r
    e_t = np.zeros(n)
    e_t[jm] = 1.0
    e_f = np.zeros(n)
    e_f[ix] = 1.0
    b_t, b_f = np.zeros(nx), np.zeros(nx)
    acc_t = minv @ (r.T @ e_t)              # acceleration per unit applied torque
    b_f[nr:2 * nr] = minv @ (r.T @ e_f)
    if lag:
        a[nr:2 * nr, -1] = acc_t
        a[-1, -1] = -1.0 / p.torque_lag
        b_t[-1] = 1.0 / p.torque_lag
    else:
        b_t[nr:2 * nr] = acc_t
    rows = _rows(p, a, b_t, b_f, rr, nx, jm, bodies.nuts, lag)
    return Plant(a=a, b_t=b_t, b_f=b_f, rows=rows, lag=lag, state=state, op=op)


def _rows(p, a, b_t, b_f, rr, nx, jm, nuts, lag):
    """Return the output rows of :class:`Plant` (row over X, coefficient on T_c, on F)."""
    n = rr.shape[0] // 2
    nr = rr.shape[1] // 2

    def unit(i):                            # the coordinate (or rate) i of z = [y, y'] over X
        out = np.zeros(nx)
        out[:2 * nr] = rr[i]
        return out

    ix = nuts[0]
    rows = dict(q_m=(unit(jm), 0.0, 0.0), w_m=(unit(n + jm), 0.0, 0.0),
                x=(unit(ix), 0.0, 0.0), v=(unit(n + ix), 0.0, 0.0))
    # axial thread force on the nut bodies: sum m_i x_i'' + c_x x' - F, their own
    # balance (the preload spring's forces on the two halves cancel; stuck, it
    # includes the friction's reaction)
    force = [p.guide_viscous * rows['v'][0], 0.0, -1.0]
    for i, m_i in zip(nuts, (p.nut_mass + p.payload_mass, p.second_nut_mass)):
        row_v = unit(n + i)
        force[0] = force[0] + m_i * (row_v @ a)
        force[1] += m_i * (row_v @ b_t)
        force[2] += m_i * (row_v @ b_f)
    rows['force'] = tuple(force)
    if lag:
        e = np.zeros(nx)
        e[-1] = 1.0
        rows['torque'] = (e, 0.0, 0.0)
    else:
        rows['torque'] = (np.zeros(nx), 1.0, 0.0)
    return rows
