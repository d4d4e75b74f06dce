"""
Frequency response of the axis (doc/frequency_response.md): linear, simulated and from a recording.

- :mod:`.response`: :class:`FrequencyResponse`, what every source returns.
- :mod:`.plant`, :mod:`.linear`, :mod:`.loops`: the linearised axis (at rest
  on a flank or sliding), its drive (continuous, sampled at the drive period,
  or held at the step), the loop quantities L, S, T.
- :mod:`.sine`, :mod:`.broadband`, :mod:`.drive_runs`, :mod:`.parallel`: the
  simulated measurement through the full model (sine dwell, multisine, chirp).
- :mod:`.signals`: the chirp and the multisine as functions of time.
- :mod:`.welch`: H1 and coherence of a recording.
- :mod:`.measure`: the library calls (:func:`linear_response`,
  :func:`simulated_response`); :mod:`.summary`: resonances, bandwidth,
  margins; :mod:`.output`: CSV and Bode PNG.
"""
from .measure import linear_response, simulated_response
from .response import FrequencyResponse

__all__ = ['FrequencyResponse', 'linear_response', 'simulated_response']
