"""
Broadband test signals of a frequency response: a chirp and a multisine (functions of time).

Both are plain functions of a time array [s], shared by the simulated
measurement (:mod:`.simulated`) and the ``excite chirp`` / ``excite multisine``
profiles, so a recording and a simulation see the same signal:

- :func:`chirp`: a sine whose frequency sweeps from f0 to f1 [Hz] over a
  duration, logarithmically (default: equal time per decade) or linearly,
  zero at t = 0 and held at zero outside [0, duration];
- :func:`multisine`: a sum of sines at given frequencies [Hz] with Schroeder
  phases (a low crest factor), scaled so its peak bound is the amplitude;
  periodic in 1 / gcd of the frequencies when they are multiples of one base.
- :func:`multisine_frequencies`: log-spaced lines on the grid of a base
  frequency (whole periods of the record), at most one per bin.
"""
import math

import numpy as np

__all__ = ['chirp', 'chirp_frequency', 'multisine', 'multisine_frequencies', 'schroeder_phases',
           'SWEEPS']

#: The chirp's sweep laws.
SWEEPS = ('log', 'linear')


def _check_band(f0, f1):
    if not (math.isfinite(f0) and math.isfinite(f1) and 0.0 < f0 < f1):
        raise ValueError(f'frequency band: need 0 < f0 < f1, got f0={f0!r} Hz, f1={f1!r} Hz')


def chirp_frequency(t, f0, f1, duration, sweep='log'):
    """
    Return the instantaneous frequency [Hz] of :func:`chirp` at times t [s].

    Parameters
    ----------
    t : array_like
        Times [s].
    f0, f1 : float
        Start and end frequency [Hz], 0 < f0 < f1.
    duration : float
        Sweep time [s] > 0.
    sweep : str
        'log' or 'linear'.

    """
    _check_band(f0, f1)
    tau = np.clip(np.asarray(t, dtype=float) / duration, 0.0, 1.0)
    if sweep == 'log':
        return f0 * (f1 / f0) ** tau
    return f0 + (f1 - f0) * tau


def chirp(t, f0, f1, duration, amplitude=1.0, sweep='log'):
    """
    Return a swept sine amplitude sin(phi(t)) at times t [s]; zero outside [0, duration].

    The phase phi(t) = 2 pi integral_0^t f(s) ds starts at 0 (so the signal
    starts at 0); f(t) = f0 (f1 / f0)^(t / T) ('log') or f0 + (f1 - f0) t / T
    ('linear').

    Parameters
    ----------
    t : array_like
        Times [s].
    f0, f1 : float
        Start and end frequency [Hz], 0 < f0 < f1.
    duration : float
        Sweep time T [s] > 0.
    amplitude : float
        Peak value, in the unit of the signal it drives.
    sweep : str
        'log' or 'linear'.

    """
    _check_band(f0, f1)
    if not (duration > 0.0 and math.isfinite(duration)):
        raise ValueError(f'duration: {duration!r} s must be positive and finite')
    if sweep not in SWEEPS:
        raise ValueError(f'sweep: {sweep!r} is not one of {", ".join(SWEEPS)}')
    t = np.asarray(t, dtype=float)
    tc = np.clip(t, 0.0, duration)
    if sweep == 'log':
        k = math.log(f1 / f0) / duration
        phase = 2.0 * math.pi * f0 * np.expm1(k * tc) / k
    else:
        phase = 2.0 * math.pi * (f0 * tc + 0.5 * (f1 - f0) * tc * tc / duration)
    out = amplitude * np.sin(phase)
    return np.where((t >= 0.0) & (t <= duration), out, 0.0)


def schroeder_phases(n):
    """Return Schroeder's phases [rad] of n equal-amplitude lines: -pi k (k - 1) / n, k = 1..n."""
    k = np.arange(1, n + 1, dtype=float)
    return -math.pi * k * (k - 1.0) / n


def multisine(t, frequencies, amplitude=1.0, phases=None):
    """
    Return a multisine at times t [s]: amplitude / n sum_k cos(2 pi f_k t + phi_k).

    Every line has the amplitude ``amplitude / n`` (n lines), so |u| never
    exceeds ``amplitude``; Schroeder phases by default keep the actual peak
    well below that bound.

    Parameters
    ----------
    t : array_like
        Times [s].
    frequencies : array_like
        Line frequencies [Hz], positive.
    amplitude : float
        Bound of the peak value, in the unit of the signal it drives.
    phases : array_like, optional
        Phase of each line [rad]; default :func:`schroeder_phases`.

    """
    f = np.atleast_1d(np.asarray(frequencies, dtype=float))
    if len(f) == 0 or not (np.isfinite(f).all() and (f > 0.0).all()):
        raise ValueError(f'frequencies: need one or more positive frequencies [Hz], got {f!r}')
    ph = schroeder_phases(len(f)) if phases is None else np.asarray(phases, dtype=float)
    t = np.asarray(t, dtype=float)
    out = np.zeros_like(t)
    for fk, pk in zip(f, ph):
        out += np.cos(2.0 * math.pi * fk * t + pk)
    return (amplitude / len(f)) * out


def multisine_frequencies(f0, f1, period, points):
    """
    Return up to ``points`` log-spaced line frequencies [Hz] in [f0, f1] on the grid k / period.

    Each line is a whole number of cycles in ``period`` [s] (so the signal is
    periodic in it); lines that round to the same bin are merged, so fewer
    may come back.

    Parameters
    ----------
    f0, f1 : float
        Band [Hz], 0 < f0 < f1.
    period : float
        The signal's period [s]; f0 >= 1 / period.
    points : int
        Lines wanted (>= 1).

    """
    _check_band(f0, f1)
    k = np.unique(np.round(np.geomspace(f0, f1, int(points)) * period).astype(int))
    k = k[k >= 1]
    return k / period
