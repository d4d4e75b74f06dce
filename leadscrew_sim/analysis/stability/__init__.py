"""
Stability of steady sliding: when does the axis stick-slip or squeal (doc/stability.md).

- :mod:`.operating_point`: the steady sliding state at a nut speed.
- :mod:`.linearise`: its linearisation and eigenvalues.
- :mod:`.linear`: growth rate, frequency and mechanism (:func:`linear_stability`).
- :mod:`.nonlinear`: the full model from a small and a large start
  (:func:`nonlinear_stability`): amplitude, stick fraction, period, verdict.
- :mod:`.grid`: the axes ``NAME=START:STOP:N[:log]``, the cases, one row per case.
- :mod:`.executors`: the cases in this process, on local workers or on Dask.
- :mod:`.table`: the verb's library call (:func:`stability_table`): rows, CSV,
  summary; :mod:`.plot`: the PNG map.
"""
from .linear import linear_stability, MECHANISMS
from .nonlinear import nonlinear_stability, VERDICTS
from .operating_point import operating_point
from .table import stability_table

__all__ = ['linear_stability', 'MECHANISMS', 'nonlinear_stability', 'operating_point',
           'stability_table', 'VERDICTS']
