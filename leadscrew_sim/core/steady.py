"""
Steady sliding placed into a model, and runs with the motor angle prescribed.

The stability analysis starts the full model on the steady sliding state it
computed (or with the thread stuck while the drive turns), and for the ideal
drive prescribes the motor's angle after every step. These touch the model's
state vector, so they live in the core beside the model.
"""
import numpy as np

from .drive_modes import MODE_VELOCITY
from .engine import layout as L

__all__ = ['place_sliding', 'run_prescribed_motor']


def place_sliding(model, op, stuck=False, velocity_factor=1.0):
    """
    Put a model on a steady sliding state, in place (q sense of the state).

    Parameters
    ----------
    model : LeadScrewModel
        A new model of the axis.
    op : dict
        The operating point: omega [rad/s], twist (motor less screw angle)
        [rad], rigid (bool), delta0 (contact deflection) [m], torque (the
        motor's) [N m], Fa0 (axial thread force) [N], drive ('velocity' or
        'ideal'), and for the velocity drive w_ref [rad/s] and integral [N m].
    stuck : bool
        Screw and nut at rest instead, while the motor turns.
    velocity_factor : float
        Multiplies the nut's velocity after the placement (a perturbation).

    """
    s, P = model.state, model._P
    hs = model.params.hand_sign
    q0, omega = s[L.S_Q], op['omega']
    rate = 0.0 if stuck else omega
    s[L.S_Q] = q0
    s[L.S_DQ] = rate
    s[L.S_QM] = q0 + op['twist']
    s[L.S_WM] = omega if not op['rigid'] else rate
    s[L.S_XA] = P[L.P_RT] * q0 + op['delta0']
    s[L.S_VA] = rate * P[L.P_RT]
    s[L.S_XB] = s[L.S_XA]
    if len(op.get('deltas', ())) == 2:        # a split nut's half B on its own flank
        s[L.S_XB] = P[L.P_RT] * q0 + op['deltas'][1]
        s[L.S_VB] = s[L.S_VA]
    s[L.S_TE] = s[L.S_DTOUT] = op['torque']
    s[L.S_FAPREV] = op['Fa0']
    s[L.S_EQ], s[L.S_EW] = s[L.S_QM], s[L.S_WM]
    s[L.S_XS], s[L.S_VS] = s[L.S_XA], s[L.S_VA]
    if op['drive'] == 'velocity':
        model.command('velocity', velocity=hs * op['w_ref'], effort=0.0)
        s[L.S_DMODE] = MODE_VELOCITY
        s[L.S_DINT] = op['integral']
        s[L.S_DWREF] = op['w_ref']
    if op.get('stepper') is not None:
        _place_stepper(s, P, op['stepper'][2], 0.0 if stuck else omega)
    if velocity_factor != 1.0:
        s[L.S_VA] *= velocity_factor


def _place_stepper(s, P, phi, rate):
    """Put the step generator phi [rad] ahead of the rotor at rate [rad/s], currents on set."""
    pos = s[L.S_QM] + phi
    k = round((pos - P[L.P_DQ0]) / P[L.P_USTEP])
    angle = P[L.P_NR] * k * P[L.P_USTEP]
    s[L.S_SPOS], s[L.S_SRATE], s[L.S_SK], s[L.S_SIDLE] = pos, rate, k, 0.0
    s[L.S_IA] = P[L.P_IRUN] * np.cos(angle)
    s[L.S_IB] = P[L.P_IRUN] * np.sin(angle)


def run_prescribed_motor(model, n, omega):
    """
    Run n steps with the motor (or a rigid coupling's screw) angle prescribed to turn at omega.

    The coupling's torque of the current state drives the screw each step;
    after it the motor is put back on its ramp. Returns (nut velocity [m/s],
    stuck: 1.0 or 0.0) of each step.

    Parameters
    ----------
    model : LeadScrewModel
        A model placed on its start (see :func:`place_sliding`).
    n : int
        Steps.
    omega : float
        The motor's rate [rad/s], q sense.

    """
    s, p = model.state, model.params
    hs, dt = p.hand_sign, model.dt
    kc, cc = p.coupling_stiffness, p.coupling_damping
    rigid = kc == 0.0
    qm0 = s[L.S_QM]
    vel, stuck = np.empty(n), np.empty(n)
    for i in range(n):
        torque = 0.0 if rigid else kc * (s[L.S_QM] - s[L.S_Q]) + cc * (s[L.S_WM] - s[L.S_DQ])
        model.advance(hs * torque)
        qm = qm0 + omega * dt * (i + 1)
        if rigid:
            s[L.S_Q], s[L.S_DQ] = qm, omega
        s[L.S_QM], s[L.S_WM] = qm, omega
        vel[i] = s[L.S_VA]
        stuck[i] = 1.0 if model.out[L.O_STICKA] == 1.0 else 0.0
    return vel, stuck
