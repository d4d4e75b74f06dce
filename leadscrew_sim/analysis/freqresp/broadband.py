"""
Broadband simulated measurements: one run with a multisine or a chirp (faster than a sine dwell).

- ``multisine``: the period P is a whole number of steps, 1 / P close to
  fmin; the lines are log-spaced on the grid k / P in [fmin, fmax]
  (:func:`.signals.multisine_frequencies`, Schroeder phases); the first
  periods (at least ``settle_time``) are discarded and over each period kept
  the DFT at every line gives U_j, Y_j: H = sum conj(U_j) Y_j / sum |U_j|^2,
  coherence |sum conj(U_j) Y_j|^2 / (sum |U_j|^2 sum |Y_j|^2) (the periods' scatter).
- ``chirp``: a logarithmic sweep fmin -> fmax (:func:`.signals.chirp`), then
  H1 = P_uy / P_uu and coherence |P_uy|^2 / (P_uu P_yy) (Welch, Hann
  segments of at least four periods of fmin, half overlapping),
  interpolated onto the asked frequencies.
"""
import math

import numpy as np

from .drive_runs import run_signal
from .signals import chirp, multisine, multisine_frequencies

__all__ = ['chirp_response', 'multisine_response']


def multisine_response(params, where, output, fmin, fmax, points, amplitude, dt=1e-3,
                       periods=4, settle_time=0.2, mode='position', pair=None):
    """
    Return dict(frequency [Hz], response, coherence) of a multisine run.

    Parameters
    ----------
    params : ScrewParams
        The axis.
    where, output : str
        Input (or loop injection) and output names.
    fmin, fmax : float
        Band [Hz].
    points : int
        Lines wanted (fewer where they share a bin).
    amplitude : float
        Peak bound of the signal, in the input's unit.
    dt : float
        Step [s].
    periods : int
        Periods kept.
    settle_time : float
        Least time discarded [s] (at least one period).
    mode : str
        Drive mode under an external force.
    pair : callable, optional
        (input, output) -> (input, output) for a loop quantity.

    """
    n_per = max(4, int(round(1.0 / (fmin * dt))))
    period = n_per * dt
    lines = multisine_frequencies(max(fmin, 1.0 / period), fmax, period, points)
    lines = lines[lines < 0.5 / dt]
    settle = max(1, int(math.ceil(settle_time / period)))
    n = n_per * (settle + periods)
    t = np.arange(1, n + 1) * dt
    u, y = run_signal(params, where, multisine(t, lines, amplitude), dt, mode, output)
    if pair is not None:
        u, y = pair(u, y)
    k = n_per * periods
    bins = np.round(lines * period).astype(int)
    cu = np.fft.rfft(u[-k:].reshape(periods, n_per), axis=1)[:, bins]
    cy = np.fft.rfft(y[-k:].reshape(periods, n_per), axis=1)[:, bins]
    cross = np.sum(np.conj(cu) * cy, axis=0)
    pu = np.sum(np.abs(cu) ** 2, axis=0)
    py = np.sum(np.abs(cy) ** 2, axis=0)
    with np.errstate(divide='ignore', invalid='ignore'):
        coh = np.minimum(1.0, np.abs(cross) ** 2 / (pu * py))
        return dict(frequency=lines, response=cross / pu, coherence=coh)


def chirp_response(params, where, output, fmin, fmax, frequency, amplitude, dt=1e-3,
                   duration=None, settle_time=0.2, mode='position', pair=None):
    """
    Return dict(frequency [Hz], response, coherence) of a chirp run, at the asked frequencies.

    Parameters are those of :func:`multisine_response`, with ``frequency`` the
    frequencies [Hz] to report and ``duration`` the sweep time [s] (default
    max(2 s, 40 / fmin)); ``settle_time`` of rest is run first and discarded.
    """
    from scipy.signal import csd, welch
    dur = max(2.0, 40.0 / fmin) if duration is None else float(duration)
    n0 = int(round(settle_time / dt))
    n = n0 + int(round(dur / dt))
    t = np.arange(1, n + 1) * dt - n0 * dt
    u, y = run_signal(params, where, chirp(t, fmin, fmax, dur, amplitude), dt, mode, output)
    if pair is not None:
        u, y = pair(u, y)
    u, y = u[n0:], y[n0:]
    nper = min(len(u), max(int(round(4.0 / (fmin * dt))), len(u) // 8))
    fs = 1.0 / dt
    f, puu = welch(u, fs, nperseg=nper)
    _, pyy = welch(y, fs, nperseg=nper)
    _, puy = csd(u, y, fs, nperseg=nper)
    with np.errstate(divide='ignore', invalid='ignore'):
        h = puy / puu
        coh = np.minimum(1.0, np.abs(puy) ** 2 / (puu * pyy))
    fq = np.asarray(frequency, float)
    hr = np.interp(fq, f, h.real) + 1j * np.interp(fq, f, h.imag)
    return dict(frequency=fq, response=hr, coherence=np.interp(fq, f, coh))
