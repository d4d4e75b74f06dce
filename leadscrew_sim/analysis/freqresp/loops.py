"""
The drive's loop quantities at a controller's summing point: L = C P, S = 1 / (1 + L), T = L S.

The loop is broken where a drive's tuning tool injects, between the
controller and the plant: the velocity loop at the torque command (C the PI
K_v (1 + 1 / (T_i s)), P from torque command to the motor rate the drive
reads), the position loop at the velocity reference (C = K_p, P from the
velocity reference to the position feedback with the velocity loop closed).
Sampled at the drive period T_d (sampling 'drive' or 'step'), the loop is
that of the drive as it runs: the torque held over T_d, C(z) = K_v + (K_v /
T_i) T_d / (z - 1), P(z) the exact zero-order-hold discretisation;
'continuous' leaves the sampling out.
"""
import math

import numpy as np

from ...core.drive_control import drive_period
from ...core.params import ParameterError
from .linear import _Drive, _steps_per_period, LinearSystem, LOOPS, QUANTITIES, SAMPLINGS, zoh
from .plant import plant

__all__ = ['loop_gain', 'loop_response']


def _velocity_loop(p, pl, f, td):
    """Return L of the velocity loop at f [Hz] (td 0: continuous)."""
    w_row = pl.rows['w_m'][0]
    kv, ti = p.velocity_gain, p.velocity_integral_time
    w = 2.0 * math.pi * np.asarray(f, float)
    if td > 0.0:
        phi, gam = zoh(pl.a, pl.b_t[:, None], td)
        g = LinearSystem(phi, gam[:, 0], w_row, 0.0, td).response(f) * np.exp(-1j * w * td)
        z = np.exp(1j * w * td)
        c = kv + (kv / ti * td / (z - 1.0) if ti > 0.0 else 0.0)
    else:
        g = LinearSystem(pl.a, pl.b_t, w_row, 0.0).response(f)
        c = kv * (1.0 + (1.0 / (ti * 1j * w) if ti > 0.0 else 0.0))
    return c * g


def _position_loop(p, pl, f, td):
    """Return L of the position loop at f [Hz] (td 0: continuous)."""
    drv = _Drive(p, pl, 'velocity', 'w_ff')
    w = 2.0 * math.pi * np.asarray(f, float)
    if td > 0.0:
        a, b = drv.sampled(td)
        c = np.zeros(len(b))
        c[:drv.n] = drv.q_fb[0]
        g = LinearSystem(a, b, c, 0.0, td).response(f) * np.exp(-1j * w * td)
    else:
        a, b = drv.continuous()
        g = LinearSystem(a, b, drv.q_fb[0], 0.0).response(f)
    return p.position_gain * g


def _step_sensitivity(p, pl, loop, f, dt):
    """
    Return S as a run at step dt measures it, or None when dt is not whole drive periods.

    The injection d is held over each step, the controller's total output u is
    the one of the last drive update of the step (the drive's torque, or its
    velocity reference K_p e + d), paired with d of that step: S = u / d.
    """
    td = drive_period(p, dt)
    k, whole = _steps_per_period(p, dt, td)
    if not whole:
        return None
    drv = _Drive(p, pl, 'velocity' if loop == 'velocity' else 'position',
                 't_ff' if loop == 'velocity' else 'w_ff')
    a, b = drv.sampled(td)
    a_k = np.linalg.matrix_power(a, k)
    b_k = sum(np.linalg.matrix_power(a, i) @ b for i in range(k))
    c = np.zeros(len(b))
    if loop == 'velocity':
        c[drv.n] = 1.0                       # the torque held from the last update
        d = 0.0
    else:
        c[drv.n + 1] = p.position_gain       # K_p e of the last update, + d
        d = 1.0
    return LinearSystem(a_k, b_k, c, d, dt).response(f)


def loop_gain(params, loop, frequency, speed=0.0, sampling='drive', dt=1e-3, rest='stuck'):
    """
    Return L(f) of a loop (complex, dimensionless) and a note on its sampling.

    Parameters
    ----------
    params : ScrewParams
        The axis.
    loop : str
        'velocity' or 'position'.
    frequency : array_like
        [Hz].
    speed : float
        Operating point nut speed [m/s] (0: at rest).
    sampling : str
        One of SAMPLINGS ('step': as a run at the step measures it by injection,
        when the step is whole drive periods; else as 'drive').
    dt : float
        Step [s] (sets the substep grid and so the drive period).
    rest : str
        At rest: 'stuck' or 'free' thread.

    """
    if loop not in LOOPS:
        raise ParameterError('loop', f'{loop!r} is not one of {", ".join(LOOPS)}')
    if sampling not in SAMPLINGS:
        raise ParameterError('sampling', f'{sampling!r} is not one of {", ".join(SAMPLINGS)}')
    p = params
    if p.velocity_gain <= 0.0 or (loop == 'position' and p.position_gain <= 0.0):
        raise ParameterError('velocity_gain' if p.velocity_gain <= 0.0 else 'position_gain',
                             'must be > 0 for the loop to exist')
    pl = plant(p, speed, rest)
    if sampling == 'step':
        sens = _step_sensitivity(p, pl, loop, frequency, dt)
        if sens is not None:
            return (1.0 - sens) / sens, (f'loop as measured at the {1.0 / dt:g} Hz step: '
                                         'injection held over each step, the controller '
                                         'output of its last drive update')
    td = 0.0 if sampling == 'continuous' else drive_period(p, dt)
    fn = _velocity_loop if loop == 'velocity' else _position_loop
    note = ('continuous loop' if td == 0.0 else
            f'loop sampled at the drive period {td:.6g} s, torque held')
    return fn(p, pl, frequency, td), note


def loop_response(params, loop, quantity, frequency, speed=0.0, sampling='drive', dt=1e-3,
                  rest='stuck'):
    """
    Return (H, note): L, S = 1 / (1 + L) or T = L / (1 + L) of a loop at f [Hz].

    Parameters are those of :func:`loop_gain`, and ``quantity`` one of 'L', 'S', 'T'.
    """
    if quantity not in QUANTITIES:
        raise ParameterError('quantity', f'{quantity!r} is not one of {", ".join(QUANTITIES)}')
    lg, note = loop_gain(params, loop, frequency, speed, sampling, dt, rest)
    h = {'L': lg, 'S': 1.0 / (1.0 + lg), 'T': lg / (1.0 + lg)}[quantity]
    return h, note
