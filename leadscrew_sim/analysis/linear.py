"""
The linear design of the drive gains and the closed-loop figures that document each preset.

The rigid, frictionless axis seen at the motor (:func:`total_inertia`) under
the drive's cascade, sampled at the drive period with the torque held:
:func:`design_gains` is the rule of the shipped gains, :func:`closed_loop`
the sampled loop, :func:`loop_response` its bandwidths and step figures
(the gains table of doc/model.md). The drive's update period is the
model's (:func:`leadscrew_sim.core.drive_control.drive_period`).
"""
import math

import numpy as np

from ..core.drive_control import drive_period

__all__ = ['closed_loop', 'design_gains', 'KP_DIVISOR', 'loop_response', 'TI_FACTOR',
           'total_inertia']

#: Design rule of the shipped gains: T_i = TI_FACTOR / w_v, K_p = w_v / KP_DIVISOR.
TI_FACTOR = 4.0
KP_DIVISOR = 5.0


def total_inertia(p):
    """
    Return J_total = J_m + J_s + (m_n + m_p (+ m_b)) rt^2 [kg m^2], the rigid axis at the motor.

    Parameters
    ----------
    p : ScrewParams
        The parameters.

    """
    rt = p.r_m * math.tan(p.lead_angle)
    return p.motor_inertia + p.screw_inertia + p.moving_mass * rt * rt


def design_gains(p, velocity_bandwidth):
    """
    Return (K_v [N m s/rad], T_i [s], K_p [1/s]) for a velocity-loop bandwidth w_v [rad/s].

    K_v = w_v J_total (the velocity loop's crossover on the rigid axis),
    T_i = TI_FACTOR / w_v, K_p = w_v / KP_DIVISOR: the rule of the shipped presets.

    Parameters
    ----------
    p : ScrewParams
        The parameters (inertias, masses, lead).
    velocity_bandwidth : float
        w_v [rad/s].

    """
    w = float(velocity_bandwidth)
    return w * total_inertia(p), TI_FACTOR / w, w / KP_DIVISOR


def closed_loop(j, kv, ti, kp, td):
    """
    Return (A, b_pos, b_vel): the rigid axis under the drive, sampled at the drive period.

    State [q, w, I] just before a drive update; the torque is held over td
    (zero-order hold: exact for the plant J s^2 between updates). b_pos is the
    input vector of q_ref in position mode, b_vel that of w_ref in velocity
    mode; A is the position-mode matrix (the velocity mode's has K_p = 0, and
    its [w, I] block A[1:, 1:] is the velocity loop on its own).

    Parameters
    ----------
    j : float
        Inertia [kg m^2].
    kv : float
        Velocity gain [N m s/rad].
    ti : float
        Integral time [s]; 0: no integral.
    kp : float
        Position gain [1/s]; 0 for the velocity loop alone.
    td : float
        Drive period [s].

    """
    gi = kv / ti if ti > 0.0 else 0.0
    # T = kv e + gi I with e = kp (q_ref - q) - w (position) or w_ref - w (velocity)
    de = np.array([-kp, -1.0, 0.0])            # de/dx
    dt_dx = kv * de + np.array([0.0, 0.0, gi])  # dT/dx
    hold = np.array([td * td / (2.0 * j), td / j, 0.0])
    a = np.array([[1.0, td, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])
    a = a + np.outer(hold, dt_dx)
    if ti > 0.0:
        a[2] += td * de
    e_in = np.array([0.0, 0.0, td if ti > 0.0 else 0.0])
    b_pos = hold * kv * kp + e_in * kp
    b_vel = hold * kv + e_in
    return a, b_pos, b_vel


def loop_response(p, dt=1e-3, nsub=None):
    """
    Return the linear design figures of the drive gains of p on the rigid, frictionless axis.

    Parameters
    ----------
    p : ScrewParams
        The parameters (gains, drive rate, inertias).
    dt : float
        Step [s] (sets the substep grid and so the effective drive period).
    nsub : int, optional
        Substeps per step; default the model's for p and dt.

    Returns
    -------
    dict
        j_total [kg m^2]; w_v = K_v / J_total [rad/s]; drive_rate [Hz] (effective);
        f_vel, f_pos: -3 dB bandwidths of the velocity loop (w / w_ref) and the
        position loop (q / q_ref) [Hz], sampled at the drive period;
        overshoot [-] and settling_time (2 %) [s] of a small position step.

    """
    td = drive_period(p, dt, nsub)
    j = total_inertia(p)
    kv, ti, kp = p.velocity_gain, p.velocity_integral_time, p.position_gain
    a_pos, b_pos, _ = closed_loop(j, kv, ti, kp, td)
    a_vel, _, b_vel = closed_loop(j, kv, ti, 0.0, td)

    def bandwidth(a, b, out):
        eye = np.eye(len(b))
        dc = out @ np.linalg.solve(eye - a, b)
        w_nyq = math.pi / td
        ws = np.geomspace(1e-2, w_nyq, 4000)
        mags = np.array([abs(out @ np.linalg.solve(np.exp(1j * w * td) * eye - a, b)) for w in ws])
        low = np.nonzero(mags < abs(dc) / math.sqrt(2.0))[0]
        return ws[low[0]] / (2 * math.pi) if len(low) else w_nyq / (2 * math.pi)

    x = np.zeros(3)
    ys = []
    for _ in range(int(math.ceil(10.0 / (max(kp, 1e-3) * td)))):
        ys.append(x[0])
        x = a_pos @ x + b_pos
        if len(ys) > 200000:
            break
    ys = np.array(ys)
    outside = np.nonzero(np.abs(ys - 1.0) > 0.02)[0]
    settle = (outside[-1] + 1) * td if len(outside) else 0.0
    return dict(j_total=j, w_v=kv / j, drive_rate=1.0 / td,
                f_vel=bandwidth(a_vel[1:, 1:], b_vel[1:], np.array([1.0, 0.0])),
                f_pos=bandwidth(a_pos, b_pos, np.array([1.0, 0.0, 0.0])),
                overshoot=max(0.0, ys.max() - 1.0), settling_time=settle)
