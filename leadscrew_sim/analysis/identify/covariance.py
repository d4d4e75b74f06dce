"""
The covariance of a least-squares fit of serially correlated residuals (no ROS, no I/O).

The sandwich B M B with B = (J^T J)^-1 (equilibrated, :func:`scaled_inverse`)
and M the long-run covariance of the per-step scores (Bartlett weights,
bandwidth by Andrews' AR(1) plug-in rule, :func:`sandwich`), every product
taken by :mod:`.linalg`, so no BLAS kernel changes an interval.
"""
import math

import numpy as np

from . import linalg as la


def scaled_inverse(a):
    """
    Return the inverse of the normal matrix ``a`` = J^T J, equilibrated first.

    The columns of J differ by many decades (a friction coefficient against a
    backlash the data hardly see), so ``a`` is inverted as D^-1 (D^-1 a D^-1)^-1
    D^-1 with D its root diagonal; a zero column (no sensitivity) gets an
    infinite variance instead of the zero a pseudo-inverse would give.
    """
    d = np.sqrt(np.diag(a))
    zero = d == 0.0
    ds = np.where(zero, 1.0, d)
    inv = la.pinv(a / np.outer(ds, ds), 1e-12) / np.outer(ds, ds)
    inv[zero, :] = 0.0
    inv[:, zero] = 0.0
    inv[zero, zero] = np.inf
    return inv


def _bartlett_bandwidth(scores):
    """Return Andrews' (1991) AR(1) plug-in bandwidth of Bartlett weights for ``scores``."""
    n = len(scores)
    num = den = 0.0
    for g in scores.T:
        a, b = g[:-1], g[1:]
        ss = la.dot(a, a)
        if ss == 0.0:
            continue
        rho = min(0.97, max(-0.97, la.dot(a, b) / ss))
        var = float(np.mean((b - rho * a) ** 2))
        num += 4.0 * rho ** 2 * var ** 2 / ((1.0 - rho) ** 6 * (1.0 + rho) ** 2)
        den += var ** 2 / (1.0 - rho) ** 4
    if den == 0.0:
        return 0
    return int(min(n // 4, math.ceil(1.1447 * (num / den * n) ** (1.0 / 3.0))))


def sandwich(jac, r, shape):
    """
    Return (covariance, bandwidth): the HAC sandwich covariance of a least-squares fit.

    Parameters
    ----------
    jac : numpy.ndarray
        Jacobian (n_signals * n_time, p) of the flattened residuals.
    r : numpy.ndarray
        The flattened residuals at the solution.
    shape : tuple
        (n_signals, n_time) of the residual matrix.

    """
    p = jac.shape[1]
    scores = (jac.reshape(shape + (p,)) * r.reshape(shape)[:, :, None]).sum(axis=0)
    bread = scaled_inverse(la.gram(jac))
    lag = _bartlett_bandwidth(scores)
    meat = la.gram(scores)
    for ell in range(1, lag + 1):
        gam = la.gram(scores[ell:], scores[:-ell])
        meat += (1.0 - ell / (lag + 1.0)) * (gam + gam.T)
    n_used = int(np.count_nonzero(r)) or 1
    p_eff = min(p, n_used - 1)
    meat *= n_used / max(1, n_used - p_eff)      # small-sample factor, as s^2 divides by n - p
    zero = ~np.isfinite(np.diag(bread))
    b = np.where(np.isfinite(bread), bread, 0.0)
    cov = la.mat_mat(la.mat_mat(b, meat), b)
    cov[zero, zero] = np.inf
    return cov, lag
