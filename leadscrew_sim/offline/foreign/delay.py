"""
The constant command-to-state delay of a foreign recording, estimated with its interval.

A real axis's states lag its commands by transport, controller and driver
cycles that the recording does not state. The model is time-invariant and
starts at rest when the grid starts, so delaying every command by tau
delays the re-simulated states by tau exactly: one re-simulation at
tau = 0 is enough. The estimate is the shift tau that minimises the mean
squared difference between the measured positions and the re-simulated ones
at the stamps minus tau (a grid search at a tenth of a step over
:data:`SEARCH` seconds either way, then a parabola through the three best
points).

Its interval: least squares on a shift has the standard error
sigma / sqrt(sum of the slope squared), with sigma the residual RMS at the
estimate and the slope the re-simulated signal's time derivative at the
stamps; the residuals are correlated in time (a model error is smooth), so
the count of independent residuals is reduced by the lag-one
autocorrelation rho, a factor sqrt((1 + rho) / (1 - rho)). The interval is
the estimate +-2 such errors (about 95 %). Without motion (no slope) the
delay is not determined and reported as such.
"""
import dataclasses

import numpy as np

from ..options import NS

#: Largest delay searched [s], either way.
SEARCH = 0.25


@dataclasses.dataclass
class Delay:
    """
    A command-to-state delay: its value [s], the half width of its interval [s], and how known.

    ``how``: ``set`` (the ``command_delay`` option), ``estimated``, ``not determined``
    (then ``value`` is 0 and ``half_width`` NaN) or ``uncertain`` (an
    estimate, ``estimate`` +- ``half_width``, too wide to start from: ``value``
    is 0).
    """

    value: float
    half_width: float
    how: str
    signal: str = ''
    estimate: float = 0.0

    def line(self):
        """Return the report line of the delay (its option marked ``<<command_delay>>``)."""
        if self.how == 'set':
            return f'command-to-state delay: {self.value * 1e3:.3f} ms (set by <<command_delay>>)'
        if self.how == 'estimated':
            return (f'command-to-state delay: {self.value * 1e3:.3f} ms +- '
                    f'{self.half_width * 1e3:.3f} ms (estimated from {self.signal}, about 95 %; '
                    f'<<command_delay>> sets it)')
        if self.how == 'uncertain':
            return (f'command-to-state delay: 0 used (the estimate with the starting values, '
                    f'{self.estimate * 1e3:.3f} ms +- {self.half_width * 1e3:.3f} ms, is too '
                    'uncertain to start from; <<command_delay>> sets it)')
        return ('command-to-state delay: not determined (no motion in the mapped states); 0 '
                'used, <<command_delay>> sets it')


def estimate(stamps, measured, sim_at, signal, offset=False, dt=1e-3):
    """
    Return the :class:`Delay` that best aligns the ``measured`` signal with the re-simulation.

    Parameters
    ----------
    stamps : numpy.ndarray
        State stamps [ns] relative to the grid (those with a finite ``measured`` value).
    measured : numpy.ndarray
        The measured signal at the stamps [unit].
    sim_at : callable
        ``sim_at(times_ns)`` -> (re-simulated values, their time derivatives) at
        grid times [ns] (NaN outside the run).
    signal : str
        Its name, for the report.
    offset : bool
        Remove the mean difference (a signal with an arbitrary zero).
    dt : float
        The step [s]: the search resolution is a tenth of it.

    """
    every = max(1, len(stamps) // 20000)      # the coarse search on at most 20000 states

    def misfit(tau, every=1):
        y, _dy = sim_at(stamps[::every] - int(round(tau * NS)))
        d = measured[::every] - y
        ok = np.isfinite(d)
        if ok.sum() < 3:
            return np.inf
        d = d[ok] - (d[ok].mean() if offset else 0.0)
        return float(np.mean(d ** 2))

    coarse = np.arange(-SEARCH, SEARCH + 1e-12, max(dt, SEARCH / 200))
    costs = np.array([misfit(t, every) for t in coarse])
    i = int(np.argmin(costs))
    fine = coarse[i] + np.arange(-1.0, 1.0 + 1e-9, 0.1) * (coarse[1] - coarse[0])
    fcost = np.array([misfit(t) for t in fine])
    j = int(np.clip(np.argmin(fcost), 1, len(fine) - 2))
    a, b, c = fcost[j - 1:j + 2]
    h = fine[1] - fine[0]
    den = a - 2 * b + c
    tau = float(fine[j] + (0.5 * h * (a - c) / den if den > 0 else 0.0))
    y, dy = sim_at(stamps - int(round(tau * NS)))
    d = measured - y
    ok = np.isfinite(d) & np.isfinite(dy)
    slope2 = float(np.sum(dy[ok] ** 2))
    if not ok.any() or slope2 <= 0.0 or not np.isfinite(costs[i]):
        return Delay(0.0, float('nan'), 'not determined', signal)
    r = d[ok] - (d[ok].mean() if offset else 0.0)
    sigma = float(np.sqrt(np.mean(r ** 2)))
    rho = float(np.clip(np.corrcoef(r[:-1], r[1:])[0, 1], 0.0, 0.999)) if len(r) > 3 and \
        np.std(r) > 0 else 0.0
    se = sigma / np.sqrt(slope2) * np.sqrt((1 + rho) / (1 - rho))
    if abs(tau) >= SEARCH - 2 * h:
        return Delay(0.0, float('nan'), 'not determined', signal)
    return Delay(tau, 2.0 * float(se), 'estimated', signal)
