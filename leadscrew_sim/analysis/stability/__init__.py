"""
Stability of steady sliding: when does the axis stick-slip or squeal (physics.md section 12).

- :mod:`.operating_point`: the steady sliding state at a nut speed.
- :mod:`.linearise`: its linearisation and eigenvalues.
- :mod:`.linear`: growth rate, frequency and mechanism (:func:`linear_stability`).
- :mod:`.nonlinear`: the full model from a small and a large start
  (:func:`nonlinear_stability`): amplitude, stick fraction, period, verdict.
"""
from .linear import linear_stability, MECHANISMS
from .nonlinear import nonlinear_stability, VERDICTS
from .operating_point import operating_point

__all__ = ['linear_stability', 'MECHANISMS', 'nonlinear_stability', 'operating_point',
           'VERDICTS']
