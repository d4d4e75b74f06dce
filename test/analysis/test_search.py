"""
identify's valley scan on a narrow valley with a rough floor, against its closed-form minimum.

The residuals (in noise units) of two parameters x, y are
300 (x - y), 3 (x + y - 2) and 2 sin(2 pi x / 0.01): a valley 100 times
narrower across (x - y) than along it, whose floor is rippled with a period
of 0.01 in x, as a re-simulation's cost is roughened by events that move a
step at a time. The global minimum is at x = y = 1 with a sum of squares of
0 (every residual vanishes there). On the valley's floor (x = y) the sum of
squares is 36 (x - 1)^2 + 4 sin^2(2 pi x / 0.01): the ripple's slope reaches
4 x 2 pi / 0.01 = 2513 per unit x, the floor's is 72 |x - 1|, so every
trough of the ripple within 35 of the minimum is a local minimum, and a
local fit stalls in the first its trust region meets.
"""
import numpy as np
import pytest

from leadscrew_sim.analysis.identify.search import (local_fit, restart_fit, SearchOptions,
                                                    VALLEY_GAIN, valley_scan)

PERIOD = 0.01


class _Rough:
    """The residuals of the rough valley, counting evaluations."""

    def __init__(self):
        self.nfev = 0

    def __call__(self, z):
        self.nfev += 1
        x, y = z
        return np.array([300.0 * (x - y), 3.0 * (x + y - 2.0),
                         2.0 * np.sin(2.0 * np.pi * x / PERIOD)])


OPTS = SearchOptions(np.array([-5.0, -5.0]), np.array([5.0, 5.0]), 1e-3, 1e-8, 1e-8, None, 2)


@pytest.mark.parametrize('start', [(2.0, 1.5), (0.2, 0.5), (3.0, 3.2), (-1.0, 0.0)])
def test_valley_scan_reaches_the_minimum_where_local_fits_stall(start):
    """
    The local fit (and its restarts) stall on a ripple; the valley scan ends at the minimum.

    'At the minimum' is statistical: within VALLEY_GAIN (1, in squared noise
    units) of its sum of squares 0, the least difference the scan is built to
    resolve. The stalled fits are at least 20 above it: the data would tell
    them apart.
    """
    fun = _Rough()
    res, _z = restart_fit(fun, local_fit(fun, np.array(start), OPTS), OPTS)
    assert 2.0 * res.cost > 20.0, res.x      # the trap the scan is for
    before = fun.nfev
    found = valley_scan(fun, res, OPTS)
    assert 2.0 * found.cost <= VALLEY_GAIN, (found.x, 2.0 * found.cost)
    # near the minimum: within a few ripples of x = y = 1 (the ripples' minima are 0.005
    # apart, and their floor rises as 9 (x + y - 2)^2: 1 at 1/6 from the minimum)
    np.testing.assert_allclose(found.x, [1.0, 1.0], atol=0.1)
    assert fun.nfev - before < 1000


def test_valley_scan_keeps_a_minimum_it_cannot_improve():
    """At the minimum itself the scan returns the fit it was given."""
    fun = _Rough()
    res = local_fit(fun, np.array([1.0, 1.0]), OPTS)
    assert valley_scan(fun, res, OPTS) is res


def test_no_valley_no_scan():
    """
    Parameters that do not trade off: the scan costs its Jacobian's 2 p evaluations only.

    The residuals 30 (x - 1) and 30 (y - 1) give orthogonal columns (smallest
    singular value 1 after scaling, far above the valley's 0.3); the fit is
    returned as it was.
    """
    calls = []

    def fun(z):
        calls.append(1)
        return 30.0 * (np.asarray(z) - 1.0)
    res = local_fit(fun, np.array([1.5, 0.5]), OPTS)
    before = len(calls)
    assert valley_scan(fun, res, OPTS) is res
    assert len(calls) - before == 4
