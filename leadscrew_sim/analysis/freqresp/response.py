"""
A frequency response as every source returns it: frequencies, complex gain, coherence, amplitude.

The linear model, a simulated measurement and a recording all give one
:class:`FrequencyResponse` per amplitude (the linear model and a recording
have a single one, with ``amplitude`` NaN for the linear model).
"""
from dataclasses import dataclass, field

import numpy as np

__all__ = ['FrequencyResponse']


@dataclass
class FrequencyResponse:
    """
    H(f) from ``input`` to ``output`` (or a loop quantity), one row per frequency.

    Attributes
    ----------
    frequency : ndarray
        [Hz], increasing.
    response : ndarray of complex
        Output over input, in the units of the two signals (SI).
    coherence : ndarray
        In [0, 1]; NaN where the source has none (the linear model).
    amplitude : float
        The input amplitude in the input's SI unit; NaN for the linear model.
    input, output : str
        The signal names of doc/frequency_response.md ("Signals": ``torque``, ...),
        or for a loop quantity ``input='velocity_loop'`` and ``output`` one of
        ``L``, ``S``, ``T``.
    source : str
        ``linear``, ``sine``, ``chirp``, ``multisine`` or ``recording``.
    notes : list of str
        What the figures rest on (the hold and sampling of a discretised model,
        the settling periods discarded, the Welch segments), for the summary.
    poles, zeros : ndarray of complex, optional
        The linear model's poles and finite zeros [1/s] (continuous time).
    loop_gain : ndarray of complex, optional
        For a loop quantity, L at the same frequencies (margins and peak sensitivity).
    state : str, optional
        The linear model's thread: 'sliding', 'stuck' (at rest, held by
        stiction) or 'rest' (at rest, friction left out).

    """

    frequency: np.ndarray
    response: np.ndarray
    coherence: np.ndarray
    amplitude: float
    input: str
    output: str
    source: str
    notes: list = field(default_factory=list)
    poles: np.ndarray = None
    zeros: np.ndarray = None
    loop_gain: np.ndarray = None
    state: str = None

    @property
    def magnitude_db(self):
        """20 log10 |H| [dB]."""
        with np.errstate(divide='ignore'):
            return 20.0 * np.log10(np.abs(self.response))

    @property
    def phase_deg(self):
        """Phase of H, unwrapped along frequency over its finite nonzero points [deg], else NaN."""
        h = np.asarray(self.response)
        out = np.full(h.shape, np.nan)
        ok = np.isfinite(h) & (h != 0.0)
        out[ok] = np.degrees(np.unwrap(np.angle(h[ok])))
        return out
