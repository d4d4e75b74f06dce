"""
Broadband estimate of a frequency response: H1 and coherence by Welch averaging.

doc/frequency_response.md ("From a recording"): H1 = P_uy / P_uu, coherence |P_uy|^2 / (P_uu P_yy),
the spectra averaged over Hann-windowed, half-overlapping segments
(:func:`h1`). The series are sampled on the steps' grid t_k = t_0 + k T
(:func:`align`) and paired as the simulated measurements pair them: y_k is
the state stamped t_k (the end of step k - 1), u_k the input held over the
step that ends at t_k: the command that acted over it (the last one logged
at or before t_(k-1): the node's rule that a command logged at or before a
tick acts on the step from it), or a measured effort stamped t_k. So the
estimate of a linear axis is the exact discretisation with the input held
over each step, in that pairing: H(z) = C (I - Phi z^-1)^-1 Gamma
= z C (z I - Phi)^-1 Gamma at z = e^(j w T) (the hold's half step of lag
of C (z I - Phi)^-1 Gamma, 27 deg at 150 Hz and 1 kHz, becomes a half step
of lead).
"""
import math

import numpy as np
from scipy import signal as sps

from .response import FrequencyResponse

__all__ = ['align', 'h1', 'held', 'INPUT_FLOOR', 'welch_response']

#: Bins whose input power is below this share of the band's largest carry no
#: excitation (between a multisine's lines): left out.
INPUT_FLOOR = 1e-3
#: A bin whose neighbour has this many times its input power is the Hann
#: window's skirt of a line there (a quarter of the line's power): left out,
#: since its H1 is the line's response at the wrong frequency.
SKIRT_RATIO = 3.0


def held(times, values, grid):
    """
    Return the zero-order hold of samples at the grid times: the last value at or before each.

    Parameters
    ----------
    times : array_like of int or float
        Times of the samples, increasing (ties: the last one counts).
    values : array_like of float
        The samples.
    grid : array_like
        Times to evaluate at (the same unit); NaN before the first sample.

    """
    times = np.asarray(times)
    values = np.asarray(values, dtype=float)
    i = np.searchsorted(times, np.asarray(grid), side='right') - 1
    out = values[np.clip(i, 0, max(len(values) - 1, 0))] if len(values) else \
        np.full(len(i), np.nan)
    return np.where(i >= 0, out, np.nan)


def align(t0, dt, n, input_series, output_series, effort=False, tolerance=1e-6):
    """
    Return (u, y) on the grid t_k = t0 + k dt, k = 0 .. n - 1: y_k at t_k, u_k held up to it.

    Parameters
    ----------
    t0, dt : int or float
        First grid time and step (the unit of the series' times, e.g. ns).
    n : int
        Grid points.
    input_series : (times, values)
        The input: commands with the time they were logged (each acts from
        the first tick at or after it until the next), or with ``effort`` a
        measured effort with its stamps (held over the step ending there).
        NaN where nothing is known yet.
    output_series : (stamps, values)
        The output samples with their stamps; a grid point without a sample
        is NaN.
    effort : bool
        The input is a measured effort: its value stamped t_k is u_k (else
        u_k is the command logged at or before t_(k-1)).
    tolerance : float
        Largest distance of a stamp from its grid time, as a share of dt
        (0.5: every stamp goes to the nearest step).

    """
    grid = t0 + dt * np.arange(n)
    u = held(*input_series, grid - (0 if effort else dt))
    stamps, values = (np.asarray(a) for a in output_series)
    y = np.full(n, np.nan)
    k = np.rint((stamps - t0) / dt).astype(np.int64)
    on = (k >= 0) & (k < n) & (np.abs(stamps - (t0 + k * dt)) <= tolerance * abs(dt))
    y[k[on]] = np.asarray(values, dtype=float)[on]
    return u, y


def h1(u, y, dt, segments=8, detrend='linear'):
    """
    Return (f [Hz], H1, coherence) of input u and output y sampled every dt [s].

    Parameters
    ----------
    u, y : array_like of float
        Equally long, finite series on the same grid.
    dt : float
        Sampling step [s].
    segments : int
        The record is cut into this many segments of equal length, windowed
        (Hann) and overlapped by half (2 segments - 1 averages).
    detrend : str
        Per-segment detrend of scipy.signal ('linear' or 'constant').

    """
    f, p_uu, p_yy, p_uy = _spectra(u, y, dt, segments, detrend)
    with np.errstate(divide='ignore', invalid='ignore'):
        h = p_uy / p_uu
        coh = np.abs(p_uy) ** 2 / (p_uu * p_yy)
    return f, h, np.clip(np.nan_to_num(coh), 0.0, 1.0)


def _spectra(u, y, dt, segments, detrend):
    """Return (f [Hz], P_uu, P_yy, P_uy): Welch's averages of :func:`h1`."""
    u = np.asarray(u, dtype=float)
    y = np.asarray(y, dtype=float)
    nper = len(u) // int(segments)
    if nper < 8:
        raise ValueError(f'segments: {segments} segments of {len(u)} samples are shorter than '
                         '8 samples')
    kw = dict(fs=1.0 / dt, window='hann', nperseg=nper, noverlap=nper // 2, detrend=detrend)
    f, p_uu = sps.welch(u, **kw)
    _f, p_yy = sps.welch(y, **kw)
    _f, p_uy = sps.csd(u, y, **kw)
    return f, p_uu, p_yy, p_uy


def welch_response(u, y, dt, input, output, fmin=None, fmax=None, segments=8,
                   source='recording', notes=()):
    """
    Return the :class:`FrequencyResponse` (H1, coherence) of u to y in [fmin, fmax] [Hz].

    Bins without excitation (input power below :data:`INPUT_FLOOR` of the
    band's largest, or a line's window skirt: :data:`SKIRT_RATIO`) are left
    out; ``amplitude`` is half the input's peak-to-peak [its unit].

    Parameters
    ----------
    u, y : array_like of float
        Input and output on one grid (:func:`align`), finite.
    dt : float
        Step [s].
    input, output : str
        Signal names of the response.
    fmin, fmax : float, optional
        Band [Hz]; default from the first bin above 0 to the Nyquist frequency.
    segments : int
        As :func:`h1`.
    source : str
        The response's source.
    notes : sequence of str
        What the estimate rests on.

    """
    f, h, coh = h1(u, y, dt, segments)
    p_uu = _spectra(u, y, dt, segments, 'linear')[1]
    lo = f[1] if fmin is None else fmin
    hi = 0.5 / dt if fmax is None else fmax
    band = (f >= lo) & (f <= hi) & (f > 0.0)
    if not band.any():
        raise ValueError(f'band: no frequency bin in [{lo:g}, {hi:g}] Hz (resolution '
                         f'{f[1]:g} Hz)')
    keep = band & (p_uu >= INPUT_FLOOR * p_uu[band].max()) & ~_skirts(p_uu)
    note = (f'H1 = P_uy / P_uu by Welch: {segments} Hann segments of '
            f'{len(u) // int(segments)} steps ({f[1]:.4g} Hz bins), half overlapped; input '
            f'held over each step, output at the step ends')
    amp = 0.5 * float(np.ptp(np.asarray(u, dtype=float)))
    return FrequencyResponse(frequency=f[keep], response=h[keep], coherence=coh[keep],
                             amplitude=amp if math.isfinite(amp) else math.nan,
                             input=input, output=output, source=source,
                             notes=[note, *notes])


def _skirts(p):
    """Return the bins next to one with :data:`SKIRT_RATIO` times their power."""
    out = np.zeros(len(p), dtype=bool)
    out[1:] |= p[:-1] > SKIRT_RATIO * p[1:]
    out[:-1] |= p[1:] > SKIRT_RATIO * p[:-1]
    return out
