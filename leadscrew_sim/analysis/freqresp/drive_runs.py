"""
One run of the full nonlinear model under a test signal on one input (the simulated measurement).

:func:`run_signal` starts a model at rest (its initial seating on the loaded
flank) and feeds the signal u(t_k) of each step k (held over the step that
ends at t_k) on top of the input's holding value:

- ``torque``: torque mode, about the torque that holds the axial load
  through the lead (r_t W, theta sense);
- ``velocity_command``: velocity mode about 0 (nut velocity [m/s] -> motor
  rate by the rigid kinematics);
- ``position_command``: position mode about the start position;
- ``external_force``: the force on the nut [N] under the drive mode asked for
  (position: holding the start, velocity: 0, torque: the holding torque);
- the velocity loop: velocity mode about 0, the signal injected as the
  torque feed-forward (between the PI and the plant) [N m];
- the position loop: position mode holding the start, the signal injected as
  the velocity feed-forward (between K_p and the velocity loop) [rad/s].

At a nut speed v != 0 (velocity mode only: velocity_command, the velocity
loop, external_force under mode velocity) the model starts on the steady
sliding state of the stability analysis (:func:`leadscrew_sim.core.steady.place_sliding`)
and the signal rides on the velocity reference that holds v.

A run in which the drive latches a fault (following error, torque limit)
returns a NaN output: no measurement at that point.

It returns (input sequence, output sequence) for the FRF estimators: for a
loop quantity the injection d and the controller output's total u (the
drive's torque or velocity reference): S = u / d, T = (d - u) / d,
L = (d - u) / u.
"""
import math

import numpy as np

from ...core.drive_modes import MODE_POSITION, MODE_TORQUE, MODE_VELOCITY
from ...core.model import LeadScrewModel
from ...core.params import ParameterError
from ...core.steady import place_sliding
from ..stability.operating_point import operating_point
from .plant import rest_load

__all__ = ['OUTPUT_COLUMNS', 'run_signal']

#: Output name -> the column of LeadScrewModel.run (all theta sense / +x, SI).
OUTPUT_COLUMNS = dict(motor_angle='motor_angle', motor_velocity='motor_velocity',
                      nut_position='nut_position', nut_velocity='nut_velocity',
                      thread_force='axial_force', following_error='following_error',
                      motor_torque='motor_torque')


def _holding_torque(p):
    """Return the motor torque [N m], theta sense, that holds the rest load through the lead."""
    return p.hand_sign * p.lead_ratio * rest_load(p)


def _start_angle(model):
    """Return the drive's position feedback at the start, as a motor angle [rad] (theta sense)."""
    out = model.output()
    if model.params.drive_feedback == 'linear_scale':
        return float(model.nut_to_motor(out.nut_position))
    return float(out.motor_angle)


def _rows(model, mode, n):
    """Return command rows (n, 4) holding the start in ``mode`` (theta sense)."""
    rows = np.full((n, 4), math.nan)
    if mode == 'position':
        rows[:, 0] = MODE_POSITION
        rows[:, 1] = _start_angle(model)
    elif mode == 'velocity':
        rows[:, 0] = MODE_VELOCITY
        rows[:, 2] = 0.0
    else:
        rows[:, 0] = MODE_TORQUE
        rows[:, 3] = _holding_torque(model.params)
    return rows


def _sliding(model, where, mode, speed, n, dt):
    """Place the model on steady sliding at speed [m/s]; return its velocity command (theta)."""
    p = model.params
    if where not in ('velocity_command', 'velocity_loop') and not (
            where == 'external_force' and mode == 'velocity'):
        raise ParameterError('speed', f'{speed!r} m/s: a simulated measurement while sliding '
                             'takes the velocity loop (velocity_command, loop velocity, or '
                             'external_force with mode velocity)')
    room = (p.stroke_max if speed > 0 else p.stroke_min) - p.initial_position
    if abs(speed) * n * dt >= 0.9 * abs(room):
        raise ParameterError('speed', f'{speed!r} m/s for {n * dt:.3g} s travels beyond 90 % '
                             f'of the {abs(room):.4g} m to the end stop')
    op = operating_point(p, speed, 'velocity')
    place_sliding(model, op)
    return p.hand_sign * op['w_ref']


def run_signal(params, where, u, dt, mode='position', output='motor_velocity', speed=0.0):
    """
    Run the model under signal u (one value per step) at ``where``; return (input, output).

    Parameters
    ----------
    params : ScrewParams
        The axis.
    where : str
        An input name, or 'velocity_loop' / 'position_loop' (the injection).
    u : numpy.ndarray
        The signal of each step, in the input's unit (SI, theta sense / +x).
    dt : float
        Step [s].
    mode : str
        Drive mode under an external force: 'torque', 'velocity' or 'position'.
    output : str
        The output name (ignored for a loop: the controller output comes back).
    speed : float
        Nut speed of the operating point [m/s] (0: at rest; else velocity mode only).

    Returns
    -------
    (numpy.ndarray, numpy.ndarray)
        The input as applied (for a loop the injection) and the output of each step.

    """
    p = params
    model = LeadScrewModel(p, dt=dt)
    n = len(u)
    hs, rt = p.hand_sign, p.lead_ratio
    forces = None
    w0 = _sliding(model, where, mode, speed, n, dt) if speed else 0.0
    if where == 'torque':
        res = model.run(_holding_torque(p) + u)
        return u, res[OUTPUT_COLUMNS[output]]
    if where in ('velocity_command', 'velocity_loop'):
        rows = _rows(model, 'velocity', n)
        rows[:, 2] = w0
        if where == 'velocity_command':
            rows[:, 2] += hs * u / rt
        else:
            rows[:, 3] = u
    elif where in ('position_command', 'position_loop'):
        rows = _rows(model, 'position', n)
        if where == 'position_command':
            rows[:, 1] += hs * u / rt
        else:
            rows[:, 2] = u
    else:                                   # external_force
        rows = _rows(model, mode, n)
        if mode == 'velocity':
            rows[:, 2] = w0
        forces = np.ascontiguousarray(u, dtype=float)
    res = model.run(None, forces, commands=rows)
    key = {'velocity_loop': 'drive_torque', 'position_loop': 'velocity_reference'}.get(
        where, OUTPUT_COLUMNS.get(output))
    if np.any(res['fault'] != 0):           # a latched drive fault: no measurement
        return u, np.full(n, math.nan)
    return u, res[key]
