"""
The white-noise level of a sampled signal, for a sensor whose noise is not known.

:func:`noise_estimate`: the MAD of second differences on the step grid, or
at irregular stamps the residual against the parabola through each
sample's neighbours, from the quietest windows.
"""
import math

import numpy as np

__all__ = ['noise_estimate']


def noise_estimate(y, t=None):
    """
    Return the white-noise level of a sampled signal from its second differences.

    1.4826 MAD(d2 y) / sqrt(6): the second difference of white noise has the
    variance 6 sigma^2, a smooth signal's is small, and the median absolute
    deviation ignores the few large steps. NaN samples are skipped.

    With sample times ``t`` (stamps off a regular grid), each sample is
    compared with the parabola through its neighbours i-1, i+1 and i+2,
    e_i = y_i - sum_j L_j y_j (Lagrange weights L_j at t_i), divided by its
    white-noise spread sqrt(1 + sum_j L_j^2): a motion at constant speed or
    acceleration leaves none of it however irregular the stamps are (the
    plain second difference of such samples is the speed times the jitter),
    and the level is that of the quietest windows (:func:`_quiet_level`).

    Parameters
    ----------
    y : numpy.ndarray
        The samples.
    t : numpy.ndarray, optional
        Their times (any unit; increasing), or None for equal spacing.

    """
    y = np.asarray(y, dtype=float)
    keep = np.isfinite(y)
    y = y[keep]
    if len(y) < 4:
        return 0.0
    if t is None:
        d2 = np.diff(y, 2)
        return float(1.4826 * np.median(np.abs(d2 - np.median(d2))) / math.sqrt(6.0))
    t = np.asarray(t, dtype=float)[keep]
    if len(y) < 5:
        return 0.0
    # each sample against the parabola through its neighbours i-1, i+1, i+2 (Lagrange weights)
    t0, t1, t2, t3 = t[:-3], t[1:-2], t[2:-1], t[3:]
    with np.errstate(divide='ignore', invalid='ignore'):
        l0 = (t1 - t2) * (t1 - t3) / ((t0 - t2) * (t0 - t3))
        l2 = (t1 - t0) * (t1 - t3) / ((t2 - t0) * (t2 - t3))
        l3 = (t1 - t0) * (t1 - t2) / ((t3 - t0) * (t3 - t2))
    ok = np.isfinite(l0) & np.isfinite(l2) & np.isfinite(l3)
    e = (y[1:-2] - (l0 * y[:-3] + l2 * y[2:-1] + l3 * y[3:])) / \
        np.sqrt(1.0 + l0 * l0 + l2 * l2 + l3 * l3)
    e = e[ok]
    if len(e) < 2:
        return 0.0
    return _quiet_level(e)


#: Samples per window of :func:`_quiet_level`, and the least number of windows it needs.
QUIET_WINDOW, QUIET_WINDOWS = 64, 4


def _quiet_level(e):
    """
    Return the white-noise level of normalised residuals ``e`` from their quietest windows.

    Sparse, jittered samples of a servo axis leave motion in the residuals
    wherever it moves (a position loop following 100 Hz commands moves in
    bursts between samples 2-10 ms apart), and the noise alone where it
    rests. The level of each window of :data:`QUIET_WINDOW` residuals is
    1.4826 MAD; the windows within 1.5 times the lower quartile of those
    are pooled and their 1.4826 MAD returned. On residuals that are noise
    throughout, nearly every window is pooled (a window's level spreads by
    about 14 %); with too few windows, all residuals count.
    """
    def level(x):
        return float(1.4826 * np.median(np.abs(x - np.median(x))))
    n = len(e) // QUIET_WINDOW
    if n < QUIET_WINDOWS:
        return level(e)
    windows = e[:n * QUIET_WINDOW].reshape(n, QUIET_WINDOW)
    each = np.array([level(w) for w in windows])
    quiet = windows[each <= 1.5 * np.percentile(each, 25)]
    return level(quiet.ravel())
