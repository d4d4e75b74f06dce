"""
identify's own linear algebra and bounded least squares, against numpy's LAPACK and scipy.

The oracles: numpy's SVD, least squares and pseudo-inverse (LAPACK). Both
sides are backward stable, so a singular value may differ by n eps |a| (the
bound of Weyl's theorem on a perturbation of that size), given as 100 n eps
s_0; least-squares solutions agree within 100 eps (k + k^2 |r| / (|a| |x|)) |x|
(the normwise perturbation bound of a least-squares solution, k the
condition number, r the residual). Then scipy's
``least_squares`` and ``lsq_linear`` (independent implementations) and closed
forms for the bounded fits.
"""
import math

import numpy as np
import pytest
from scipy.optimize import least_squares as scipy_least_squares
from scipy.optimize import lsq_linear

from leadscrew_sim.analysis.identify import linalg as la
from leadscrew_sim.analysis.identify.lsq import least_squares


def _graded(rng, m, n):
    """Return an m x n matrix whose columns' scales span 1 .. 1e6 (a fit's Jacobian)."""
    return rng.standard_normal((m, n)) * np.logspace(0, 6, n)[None, :]


@pytest.mark.parametrize('m,n', [(400, 1), (400, 3), (3000, 6), (7, 7)])
def test_singular_values_and_least_squares_match_lapack(m, n):
    rng = np.random.default_rng(m + n)
    a, b = _graded(rng, m, n), rng.standard_normal(m)
    s0 = np.linalg.svd(a, compute_uv=False)
    np.testing.assert_allclose(la.singular_values(a), s0, rtol=1e-10,
                               atol=100 * n * np.finfo(float).eps * s0[0])
    x0 = np.linalg.lstsq(a, b, rcond=None)[0]
    k, r = s0[0] / s0[-1], np.linalg.norm(a @ x0 - b)
    eps, x_norm = np.finfo(float).eps, np.linalg.norm(x0)
    bound = 100 * eps * (k + k ** 2 * r / (s0[0] * x_norm)) * x_norm
    assert np.linalg.norm(la.lstsq(a, b) - x0) <= bound
    np.testing.assert_allclose(la.norm(b), np.linalg.norm(b), rtol=1e-14)
    np.testing.assert_allclose(la.gram(a), a.T @ a, rtol=1e-12)


def test_qr_is_orthogonal_and_triangular():
    """Q^T keeps the norm of b, R has a's Gram matrix, and R is upper triangular."""
    rng = np.random.default_rng(5)
    a, b = _graded(rng, 200, 4), rng.standard_normal(200)
    r, qtb = la.qr(a, b)
    assert np.all(np.tril(r, -1) == 0.0)
    np.testing.assert_allclose(r.T @ r, a.T @ a, rtol=1e-10)
    np.testing.assert_allclose(np.linalg.norm(qtb), np.linalg.norm(b), rtol=1e-14)


def test_rank_deficient_pseudo_inverse_drops_the_null_space():
    """A Gram matrix with a zero column and a repeated one: numpy's pinv at the same rcond."""
    rng = np.random.default_rng(9)
    j = rng.standard_normal((50, 4))
    j[:, 3] = 0.0
    j[:, 2] = j[:, 1]
    g = j.T @ j
    np.testing.assert_allclose(la.pinv(g, 1e-12), np.linalg.pinv(g, rcond=1e-12),
                               rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(la.lstsq(j, j[:, 0]), np.linalg.lstsq(j, j[:, 0],
                               rcond=None)[0], atol=1e-12)


def _decay(t, y):
    return lambda p: p[0] * np.exp(-p[1] * t) + p[2] - y


def test_fit_of_an_exponential_matches_scipy():
    """An interior minimum: both methods reach it to their tolerances."""
    rng = np.random.default_rng(2)
    t = np.linspace(0.0, 4.0, 300)
    y = 2.0 * np.exp(-1.3 * t) + 0.5 + 0.01 * rng.standard_normal(t.size)
    lo, hi = np.array([0.0, 0.0, -1.0]), np.array([10.0, 10.0, 1.0])
    ours = least_squares(_decay(t, y), np.array([1.0, 0.5, 0.0]), lo, hi, 1e-8,
                         ftol=1e-12, xtol=1e-12, gtol=1e-12)
    ref = scipy_least_squares(_decay(t, y), [1.0, 0.5, 0.0], bounds=(lo, hi), method='trf',
                              ftol=1e-12, xtol=1e-12, gtol=1e-12)
    assert ours.success
    np.testing.assert_allclose(ours.x, ref.x, rtol=1e-6)
    np.testing.assert_allclose(ours.cost, ref.cost, rtol=1e-9)
    assert np.all(ours.active_mask == 0)


def test_rosenbrock_with_an_active_bound_ends_on_it():
    """Minimise (10 (x2 - x1^2))^2 + (1 - x1)^2 over x1 <= 0.5: x = (0.5, 0.25), cost 1/8."""
    def fun(x):
        return np.array([10.0 * (x[1] - x[0] ** 2), 1.0 - x[0]])
    res = least_squares(fun, np.array([-1.2, 1.0]), np.array([-2.0, -2.0]),
                        np.array([0.5, 2.0]), 1e-8, ftol=1e-14, xtol=1e-14, gtol=1e-14)
    np.testing.assert_allclose(res.x, [0.5, 0.25], atol=1e-7)
    assert math.isclose(res.cost, 0.125, rel_tol=1e-9)
    assert res.active_mask[0] == 1 and res.active_mask[1] == 0


def test_bounded_linear_problem_matches_lsq_linear():
    """A linear residual with two bounds active: scipy's lsq_linear (BVLS) is the oracle."""
    rng = np.random.default_rng(4)
    a = rng.standard_normal((80, 4))
    b = a @ np.array([1.0, -2.0, 0.5, 3.0]) + 0.05 * rng.standard_normal(80)
    lo, hi = np.array([-1.0, -1.0, -1.0, -1.0]), np.array([2.0, 2.0, 2.0, 2.0])
    ref = lsq_linear(a, b, bounds=(lo, hi), method='bvls', tol=1e-14)
    res = least_squares(lambda x: a @ x - b, np.zeros(4), lo, hi, 1e-8,
                        ftol=1e-15, xtol=1e-15, gtol=1e-15, max_nfev=2000)
    np.testing.assert_allclose(res.x, ref.x, atol=1e-6)
    assert res.cost <= ref.cost * (1.0 + 1e-9)


def test_evaluation_budget_stops_the_fit():
    t = np.linspace(0.0, 4.0, 100)
    y = 2.0 * np.exp(-1.3 * t) + 0.5
    res = least_squares(_decay(t, y), np.array([1.0, 0.1, 0.0]), np.full(3, -10.0),
                        np.full(3, 10.0), 1e-8, max_nfev=3)
    assert res.status == 0 and not res.success and res.nfev == 3
