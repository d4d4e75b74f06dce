"""
Stability of steady sliding: when does the axis stick-slip or squeal (physics.md section 12).

- :mod:`.operating_point`: the steady sliding state at a nut speed.
- :mod:`.linearise`: its linearisation and eigenvalues.
- :mod:`.linear`: growth rate, frequency and mechanism (:func:`linear_stability`).
"""
from .linear import linear_stability, MECHANISMS
from .operating_point import operating_point

__all__ = ['linear_stability', 'MECHANISMS', 'operating_point']
