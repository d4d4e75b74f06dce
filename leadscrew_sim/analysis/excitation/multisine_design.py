"""
A multisine of low crest factor: its phases and its exact peak (for the ``multisine`` profile).

:func:`low_crest_phases` starts from Schroeder's phases and improves them by
clipping iterations: the signal of unit lines on one period is clipped at
90 % of its peak and the lines' phases of the clipped signal are kept,
:data:`CLIP_ITERATIONS` times; the set with the lowest crest factor on the
grid wins (about 2 on log-spaced lines, against about 3 for Schroeder's
phases alone and sqrt(2 n) in phase). :func:`multisine_peak` refines the
largest samples by Newton steps on s'(t) = 0.
"""
import math

import numpy as np

from ..freqresp import signals

__all__ = ['CLIP_ITERATIONS', 'low_crest_phases', 'multisine_peak']

#: Clipping iterations of the phases.
CLIP_ITERATIONS = 100


def _grid(f, period):
    """Return (harmonic numbers, samples per period: a power of 2, 8 per fastest line)."""
    h = np.rint(np.asarray(f) * period).astype(int)
    return h, 1 << int(math.ceil(math.log2(max(64, 8 * h[-1]))))


def low_crest_phases(f, period):
    """
    Return the phases [rad] of equal lines at ``f`` [Hz] (harmonics of 1 / period) of low crest.

    Parameters
    ----------
    f : array_like
        Line frequencies [Hz], increasing, each a whole number of cycles in ``period``.
    period : float
        The signal's period [s].

    """
    h, n = _grid(f, period)
    ph = signals.schroeder_phases(len(h))
    best = (math.inf, ph)
    for _ in range(CLIP_ITERATIONS):
        spec = np.zeros(n // 2 + 1, dtype=complex)
        spec[h] = np.exp(1j * ph)
        x = np.fft.irfft(spec, n)
        crest = np.abs(x).max() / math.sqrt(float(np.mean(x * x)))
        if crest < best[0]:
            best = (crest, ph)
        lim = 0.9 * np.abs(x).max()
        ph = np.angle(np.fft.rfft(np.clip(x, -lim, lim))[h])
    return best[1]


def multisine_peak(f, phases, period):
    """
    Return max |signals.multisine(t, f, 1, phases)| over a period (Newton-refined).

    Parameters
    ----------
    f : array_like
        Line frequencies [Hz].
    phases : array_like
        Their phases [rad].
    period : float
        The signal's period [s].

    """
    f = np.asarray(f, dtype=float)
    ph = np.asarray(phases, dtype=float)
    _h, n = _grid(f, period)
    t = np.arange(n) * (period / n)
    s = signals.multisine(t, f, 1.0, ph)
    w = 2.0 * math.pi * f
    peak = 0.0
    for i in np.argsort(-np.abs(s))[:8]:
        x = t[i]
        for _ in range(8):                  # Newton on s'(t) = 0
            d1 = -(w * np.sin(w * x + ph)).sum()
            d2 = -(w * w * np.cos(w * x + ph)).sum()
            if d2 == 0.0:
                break
            x -= d1 / d2
        peak = max(peak, abs(float(signals.multisine(np.array([x]), f, 1.0, ph)[0])),
                   abs(s[i]))
    return peak
