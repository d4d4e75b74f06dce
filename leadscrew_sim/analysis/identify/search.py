"""
The searches of :func:`.fit.fit` beyond one local least-squares fit.

A re-simulation is piecewise smooth in its parameters, and the cost of a
long run from a distant start has local minima and ridges: the optimiser is
restarted where it stopped on a jump (:func:`restart_fit`), a stage that leaves
a residual above twice the noise is scanned coordinate by coordinate
(:func:`scanned`), the first stage also starts from each log-scaled
parameter moved by a factor (:func:`spread`), and a log-scaled parameter
far weaker than the others can be followed along its profile
(:func:`profiled`), and a narrow, rough valley is scanned along its own axes
(:func:`valley_scan`). Every local fit of a search takes its bounds and
options from one :class:`SearchOptions`.
"""
import dataclasses
import math

import numpy as np

from . import linalg as la
from .lsq import least_squares


@dataclasses.dataclass(frozen=True, eq=False)
class SearchOptions:
    """
    The bounds and options of the local fits of a bounded search.

    Parameters
    ----------
    lo, hi : numpy.ndarray
        Bounds of the coordinates z (see :class:`.data.Coordinate`).
    diff_step : float
        Relative step of the finite-difference Jacobian in z.
    ftol, xtol : float
        Tolerances of the local fits (:func:`.lsq.least_squares`).
    max_nfev : int or None
        Most evaluations of a local fit (None: 50 per parameter).
    p : int
        The number of fitted parameters (the default ``max_nfev`` is 50 p).

    """

    lo: np.ndarray
    hi: np.ndarray
    diff_step: float
    ftol: float
    xtol: float
    max_nfev: int
    p: int

    def replace(self, **changes):
        """Return a copy with ``changes`` (field: value)."""
        return dataclasses.replace(self, **changes)


def local_fit(fun, z, opts):
    """
    Return the bounded local least-squares fit (:func:`.lsq.least_squares`) of ``fun`` from ``z``.

    Parameters
    ----------
    fun : callable
        z -> the flattened weighted residuals.
    z : numpy.ndarray
        The starting point.
    opts : SearchOptions
        The bounds and options of the fit.

    """
    return least_squares(fun, z, opts.lo, opts.hi, opts.diff_step, ftol=opts.ftol,
                         xtol=opts.xtol, gtol=1e-10, max_nfev=opts.max_nfev or 50 * opts.p)


#: Most restarts of the whole run's stage, and the least relative cost gain that earns one.
RESTARTS, RESTART_GAIN = 3, 1e-4


def restart_fit(fun, res, opts):
    """
    Restart the optimiser where it stopped while that still lowers the cost.

    On a piecewise smooth cost the trust region collapses at a jump and the
    optimiser stops on ``xtol`` short of the minimum; a restart begins with a
    fresh trust region and a Jacobian of another step (alternately 3 and 1/3
    times ``opts.diff_step``), which steps over the jump. Returns (result, its z).

    Parameters
    ----------
    fun : callable
        z -> the flattened weighted residuals.
    res : OptimizeResult
        The fit to improve on.
    opts : SearchOptions
        The bounds and options of the local fits.

    """
    for k in range(RESTARTS):
        step = opts.diff_step * (3.0 if k % 2 == 0 else 1.0 / 3.0)
        new = local_fit(fun, res.x, opts.replace(diff_step=step))
        if not new.cost < res.cost * (1.0 - RESTART_GAIN):
            if new.cost < res.cost:
                res = new
            break
        res = new
    return res, res.x


#: RMS / noise level of a signal above which the whole run's local fit is taken for a wrong
#: minimum and a coordinate scan looks for a better basin (a fit of the right one leaves 1).
SCAN_ABOVE = 2.0

#: Half-widths of the scan's grids in z (linear: a fraction of the start; log: a factor
#: e^w), each grid of SCAN_POINTS points around the best point of the last, and its sweeps.
SCAN_WIDTHS, SCAN_POINTS, SCAN_SWEEPS = ((0.5, 1.4), (0.05, 0.14), (0.005, 0.014)), 11, 2


def scanned(fun, res, starts, coords, opts, restart):
    """
    Return the result of a coordinate scan and a local fit from it, if it lowers the cost.

    A re-simulation of stick-slip or of a drive loop over coarse sensors is so
    rough in its parameters (a breakaway a step earlier changes the rest of
    the run) that the basin of the optimum is only a few per cent wide, while
    outside it the cost still falls toward it on the large scale. A local fit
    from 20 % off then stops on a ridge. A derivative-free search follows the
    large-scale trend: each coordinate in turn is set to the best of a grid
    around its current value (the others held), the grid narrowed by 10
    twice; the sweeps start from the starting point and from the local fit,
    and the local fit is repeated from the best point found.

    Parameters
    ----------
    fun : callable
        z -> the flattened weighted residuals.
    res : OptimizeResult
        The fit to improve on.
    starts : list of numpy.ndarray
        The points the sweeps start from.
    coords : list of Coordinate
        The fitted parameters.
    opts : SearchOptions
        The bounds and options of the local fits.
    restart : bool
        Restart the last local fit as :func:`restart_fit` does.

    """
    lo, hi = opts.lo, opts.hi
    best_z, best_c = np.array(res.x), float(np.sum(res.fun ** 2))
    for zs in starts:
        z = np.array(zs, dtype=float)
        c = float(np.sum(fun(z) ** 2))
        for wide in SCAN_WIDTHS:
            for _sweep in range(SCAN_SWEEPS):
                for i, co in enumerate(coords):
                    w = wide[1] if co.log else wide[0] * max(abs(z[i]), 1e-3)
                    for zi in np.linspace(z[i] - w, z[i] + w, SCAN_POINTS):
                        zt = np.array(z)
                        zt[i] = min(hi[i], max(lo[i], zi))
                        ct = float(np.sum(fun(zt) ** 2))
                        if ct < c:
                            z, c = zt, ct
        if c < best_c:
            best_z, best_c = z, c
    if best_c >= 2.0 * res.cost:
        return res
    new = local_fit(fun, best_z, opts)
    if restart:
        new, _z = restart_fit(fun, new, opts)
    return new if new.cost < res.cost else res


#: Half-widths in ln units and points of the profile grids of a log-scaled parameter, and
#: the tolerances of the fits along it (the whole fit from its best point refines).
PROFILE_GRIDS, PROFILE_TOL = ((math.log(4.0), 13), (0.12, 5)), 1e-5


def profiled(fun, res, coords, opts):
    """
    Return the local fit from the best point of each log parameter's profile, if it is better.

    Where a few parameters are fixed a thousand times more sharply than the
    others (stick-slip slides: the friction coefficients against the Stribeck
    velocity), the local fit stops in the narrow valley of the sharp ones,
    and neither its steps nor a coordinate scan follow the valley along the
    weak one. The profile does: for each grid value of a log parameter (a
    factor 4 either way, as the first stage's spread, then +-12 % around the
    best) the others are
    fitted locally, and the whole fit is repeated from the best point.

    Parameters
    ----------
    fun : callable
        z -> the flattened weighted residuals.
    res : OptimizeResult
        The fit to improve on.
    coords : list of Coordinate
        The fitted parameters.
    opts : SearchOptions
        The bounds and options of the local fits.

    """
    lo, hi = opts.lo, opts.hi
    best = res
    for i, c in enumerate(coords):
        if not c.log or len(coords) < 2:
            continue
        others = [j for j in range(len(coords)) if j != i]
        along = opts.replace(lo=lo[others], hi=hi[others], ftol=PROFILE_TOL, xtol=PROFILE_TOL)
        centre = best.x[i]
        for width, points in PROFILE_GRIDS:
            found = None
            for zi in np.linspace(centre - width, centre + width, points):
                zi = min(hi[i], max(lo[i], zi))

                def reduced(zo, zi=zi):
                    z = np.empty(len(coords))
                    z[i], z[others] = zi, zo
                    return fun(z)

                r = local_fit(reduced, best.x[others], along)
                if found is None or r.cost < found[0]:
                    found = (r.cost, zi, r.x)
            centre = found[1]
        if found[0] < best.cost:
            z = np.empty(len(coords))
            z[i], z[others] = found[1], found[2]
            new = local_fit(fun, z, opts)
            if new.cost < best.cost:
                best = new
    return best


#: Half-widths of the valley scan's grids, in standard deviations of the local quadratic
#: model along each axis, its points per grid (the centre, already known, left out), its
#: most rounds, and the least fall of the sum of squares (noise units) that earns another.
VALLEY_WIDTHS, VALLEY_POINTS, VALLEY_ROUNDS, VALLEY_GAIN = (30.0, 3.0, 0.3), 11, 4, 1.0
#: Relative step of the valley scan's Jacobian in z: a wide step sees the trend of the
#: valley's walls over the jumps of its floor.
VALLEY_STEP = 1e-2
#: Largest smallest singular value of that Jacobian, its columns scaled to unit norm, of a
#: valley (parameters that trade off): of two columns at an angle a it is
#: sqrt(1 - |cos a|), so 0.3 is a |cos a| of 0.91. Above it the parameters do not trade
#: off and the scan is not made.
VALLEY_COLLINEAR = 0.3


def valley_scan(fun, res, opts):
    """
    Return the local fit from the best point of scans along the cost's principal axes.

    Where two parameters trade off (a friction coefficient against the
    Stribeck velocity, both read from the same slow slides) the cost is a
    long curved valley, and where the motion has events (a breakaway, a flank
    change, a stick) on the step grid its floor is rough: a change of a few
    1e-4 in a coefficient moves an event by a step and the cost by more than
    the floor's slope over it. A gradient step then stalls on the first
    ridge of the floor, and a coordinate scan crosses the valley at an angle
    and sees only its walls. This scan follows it: the Jacobian J at the
    point, by central differences of :data:`VALLEY_STEP` (the walls' trend
    over the jumps), gives the axes V and standard deviations 1 / s of the
    local quadratic model (the thin SVD J = U diag(s) V^T). Without a valley
    (no two columns of J, scaled to unit norm, within :data:`VALLEY_COLLINEAR`
    of collinear) the scan stops there: a fit of parameters that do not trade
    off has no long floor to stall on. Along each axis
    in turn the point moves to the best of a grid of +-30, 3 and 0.3 of its
    standard deviations. Rounds repeat from the new point (its own axes: the
    valley bends) while one lowers the sum of squares by at least
    :data:`VALLEY_GAIN` (noise units: less is no evidence), and the local fit
    is repeated from the best point; its result replaces ``res`` if it is
    better.

    Parameters
    ----------
    fun : callable
        z -> the flattened weighted residuals (in noise units).
    res : OptimizeResult
        The fit to improve on.
    opts : SearchOptions
        The bounds and options of the local fits.

    """
    lo, hi = opts.lo, opts.hi
    z, ssq = np.array(res.x, dtype=float), 2.0 * float(res.cost)
    start = ssq
    for _round in range(VALLEY_ROUNDS):
        jac = np.empty((res.fun.size, z.size))
        for i in range(z.size):
            h = VALLEY_STEP * max(1.0, abs(z[i]))
            up, down = np.array(z), np.array(z)
            up[i], down[i] = min(hi[i], z[i] + h), max(lo[i], z[i] - h)
            if up[i] == down[i]:
                jac[:, i] = 0.0
                continue
            jac[:, i] = (fun(up) - fun(down)) / (up[i] - down[i])
        if _round == 0 and not _collinear(jac):
            return res
        s, axes, _ = la.svd(jac)
        spread = np.where(s > 0.0, 1.0 / np.maximum(s, 1e-300), 0.0)
        before = ssq
        for width in VALLEY_WIDTHS:
            for k in range(z.size):
                centre = z
                for a in np.linspace(-width, width, VALLEY_POINTS):
                    if a == 0.0 or spread[k] == 0.0:
                        continue
                    zt = np.clip(centre + a * spread[k] * axes[:, k], lo, hi)
                    st = float(np.sum(fun(zt) ** 2))
                    if st < ssq:
                        z, ssq = zt, st
        if before - ssq < VALLEY_GAIN:
            break
    if not ssq < start:
        return res
    new = local_fit(fun, z, opts)
    return new if new.cost < res.cost else res


def _collinear(jac):
    """
    Return whether the columns of ``jac`` trade off (:data:`VALLEY_COLLINEAR`).

    A column of zeros (a parameter the signals do not see) is left out: it
    has no valley to follow, and its verdict holds it.
    """
    unit, size = la.unit_columns(jac)
    seen = size > 0.0
    if np.count_nonzero(seen) < 2:
        return False
    return bool(la.singular_values(unit[:, seen])[-1] < VALLEY_COLLINEAR)


#: Factor by which the first stage also starts each log-scaled parameter lower and higher.
SPREAD = 4.0


def spread(z, coords, lo, hi):
    """
    Return the extra starting points of the first stage: each log parameter / and x SPREAD.

    A parameter that spans decades (the Stribeck velocity) has the least certain start,
    and a start on the wrong side of the data's speeds leaves it without sensitivity.

    Parameters
    ----------
    z : numpy.ndarray
        The starting point.
    coords : list of Coordinate
        The fitted parameters.
    lo, hi : numpy.ndarray
        Bounds of z.

    """
    out = []
    for i, c in enumerate(coords):
        if c.log:
            for step in (-math.log(SPREAD), math.log(SPREAD)):
                zs = np.array(z, dtype=float)
                zs[i] = min(hi[i], max(lo[i], zs[i] + step))
                out.append(zs)
    return out
