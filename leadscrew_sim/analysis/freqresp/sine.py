"""
Sine dwell through the full nonlinear model: stepped sines, settling periods discarded.

Each frequency is one run (:func:`sine_point`): the frequency is moved onto
the step grid so a period is a whole number n_p of steps (f = 1 / (n_p dt),
n_p >= 3; as a sinestream with a fixed sample time does), the input
u_k = A sin(2 pi f t_k) is held over the step ending at t_k, the first
``settle`` periods (at least ``settle_time`` seconds) are discarded, and over
each of the ``periods`` kept the first Fourier coefficients U_j and Y_j of
input and output are taken. The estimate and its coherence:

    H = sum_j conj(U_j) Y_j / sum_j |U_j|^2,
    gamma^2 = |sum_j conj(U_j) Y_j|^2 / (sum_j |U_j|^2 sum_j P_j),

with P_j = 2 var(y over period j), the output's whole power at its
fundamental's scale: gamma^2 = 1 for a linear, noise-free response, and
falls with the periods' scatter (noise, drift, a response that is not
periodic) and with the share of the output's power outside the fundamental
(the harmonics of stick-slip, backlash impacts).
For a loop quantity the run returns the injection d and the controller
output u: S = u / d, T = (d - u) / d, L = (d - u) / u.
"""
import math

import numpy as np

from .drive_runs import run_signal

__all__ = ['estimate', 'grid_frequency', 'sine_point']

MIN_SAMPLES = 3        #: fewest steps per period (below it the first harmonic is undefined)


def grid_frequency(frequency, dt):
    """Return (f on the step grid [Hz], steps per period n_p): n_p = max(3, round(1 / (f dt)))."""
    n_p = max(MIN_SAMPLES, int(round(1.0 / (frequency * dt))))
    return 1.0 / (n_p * dt), n_p


def estimate(u, y, n_p, periods):
    """
    Return (H, coherence) from the last ``periods`` whole periods of n_p samples of u and y.

    Parameters
    ----------
    u, y : numpy.ndarray
        Input and output, one value per step.
    n_p : int
        Steps per period.
    periods : int
        Periods kept (the end of the records).

    """
    k = n_p * periods
    e = np.exp(-2j * math.pi * np.arange(n_p) / n_p)
    uu = u[-k:].reshape(periods, n_p)
    yy = y[-k:].reshape(periods, n_p)
    cu = uu @ e * (2.0 / n_p)
    cy = yy @ e * (2.0 / n_p)
    cross = np.sum(np.conj(cu) * cy)
    pu = np.sum(np.abs(cu) ** 2)
    py = np.sum(2.0 * yy.var(axis=1))
    h = cross / pu if pu > 0.0 else complex('nan')
    coh = abs(cross) ** 2 / (pu * py) if pu > 0.0 and py > 0.0 else math.nan
    return h, min(1.0, coh)


def _loop_pair(u, y, quantity):
    """Return (input, output) sequences of a loop quantity from the injection d and the total u."""
    d, tot = u, y
    return {'S': (d, tot), 'T': (d, d - tot), 'L': (tot, d - tot)}[quantity]


def sine_point(params, where, output, frequency, amplitude, dt=1e-3, settle=3, periods=5,
               settle_time=0.1, mode='position', quantity=None, speed=0.0):
    """
    Return one sine dwell point: dict(frequency [Hz], response, coherence, amplitude).

    Parameters
    ----------
    params : ScrewParams
        The axis.
    where : str
        Input name, or 'velocity_loop' / 'position_loop'.
    output : str
        Output name (unused for a loop).
    frequency : float
        Wanted frequency [Hz] (moved onto the step grid).
    amplitude : float
        Sine amplitude, in the input's unit (a loop: N m or rad/s).
    dt : float
        Step [s].
    settle, periods : int
        Periods discarded, periods kept.
    settle_time : float
        Least time discarded [s].
    mode : str
        Drive mode under an external force.
    quantity : str, optional
        'L', 'S' or 'T' for a loop.
    speed : float
        Nut speed of the operating point [m/s] (see :mod:`.drive_runs`).

    """
    f, n_p = grid_frequency(frequency, dt)
    n_settle = max(int(settle), int(math.ceil(settle_time * f)))
    n = n_p * (n_settle + int(periods))
    t = np.arange(1, n + 1) * dt
    u = amplitude * np.sin(2.0 * math.pi * f * t)
    ui, y = run_signal(params, where, u, dt, mode, output, speed)
    if quantity is not None:
        ui, y = _loop_pair(ui, y, quantity)
    if not np.isfinite(y).all():
        return dict(frequency=f, response=complex('nan'), coherence=math.nan,
                    amplitude=amplitude)
    h, coh = estimate(ui, y, n_p, int(periods))
    return dict(frequency=f, response=h, coherence=coh, amplitude=amplitude)
