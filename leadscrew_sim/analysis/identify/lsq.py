"""
A bounded trust-region least-squares fit whose path does not depend on the BLAS kernel.

The method is the trust-region reflective one of Branch, Coleman and Li
(SIAM J. Sci. Comput. 21, 1999), the ``'trf'`` of scipy's
``least_squares``, and its result has the same named fields: the bounds
enter through the Coleman-Li scaling of the variables by their distance to
the bound the gradient points at; each step solves the scaled trust-region
subproblem exactly from an SVD (Moré's iteration on the Levenberg-Marquardt
parameter), and a step that leaves the box is cut at the bound and compared
with its reflection there and with the scaled gradient step.

Why not scipy's own: its linear algebra runs on OpenBLAS, whose kernels
(one per CPU, or as ``OPENBLAS_CORETYPE`` chooses) round differently; on the
rough cost of a stick-slip re-simulation a step that differs in its last bits
ends elsewhere, so the same recording gave fits a half-width apart on two
machines. Every product here is taken by :mod:`.linalg` (numpy's own
reductions), so a fit is the same to the bit under any kernel.

The Jacobian is by forward differences of relative step ``diff_step``
(backward where the forward point leaves the box), and ``nfev`` counts the
evaluations of the steps only, as scipy's does.
"""
import math

import numpy as np
from scipy.optimize import OptimizeResult

from . import linalg as la

MESSAGES = {
    0: 'The maximum number of function evaluations is exceeded.',
    1: '`gtol` termination condition is satisfied.',
    2: '`ftol` termination condition is satisfied.',
    3: '`xtol` termination condition is satisfied.',
    4: 'Both `ftol` and `xtol` termination conditions are satisfied.',
}


def _feasible(x, lb, ub, rstep):
    """Return ``x`` moved strictly inside the box (by rstep max(1, |x|), or one ulp if 0)."""
    x = np.array(x, dtype=float)
    if rstep == 0.0:
        x = np.where(x <= lb, np.nextafter(lb, ub), x)
        x = np.where(x >= ub, np.nextafter(ub, lb), x)
    else:
        x = np.where(x <= lb, lb + rstep * np.maximum(1.0, np.abs(lb)), x)
        x = np.where(x >= ub, ub - rstep * np.maximum(1.0, np.abs(ub)), x)
    tight = (x < lb) | (x > ub)
    return np.where(tight, 0.5 * (lb + ub), x)


def _jacobian(fun, x, f0, lb, ub, rel):
    """Return the forward-difference Jacobian of ``fun`` at ``x`` (f0 = fun(x)), in the box."""
    sign = np.where(x >= 0.0, 1.0, -1.0)
    h = rel * sign * np.maximum(1.0, np.abs(x))
    out = (x + h < lb) | (x + h > ub)
    h = np.where(out, -h, h)
    h = (x + h) - x
    jac = np.empty((f0.size, x.size))
    for i in range(x.size):
        xi = np.array(x)
        xi[i] += h[i]
        jac[:, i] = (np.asarray(fun(xi), dtype=float) - f0) / h[i]
    return jac


def _scaling(x, g, lb, ub):
    """Return the Coleman-Li scaling vector v and its derivative dv."""
    v, dv = np.ones_like(x), np.zeros_like(x)
    up = (g < 0.0) & np.isfinite(ub)
    v[up], dv[up] = ub[up] - x[up], -1.0
    down = (g > 0.0) & np.isfinite(lb)
    v[down], dv[down] = x[down] - lb[down], 1.0
    return v, dv


def _to_bound(x, s, lb, ub):
    """Return (the least step t >= 0 with x + t s on a bound, which bounds it hits: -1, 0, 1)."""
    with np.errstate(divide='ignore', invalid='ignore'):
        steps = np.where(s != 0.0, np.maximum((lb - x) / s, (ub - x) / s), np.inf)
    t = float(np.min(steps))
    return t, np.where(steps == t, np.sign(s), 0.0)


def _to_sphere(x, s, radius):
    """Return the roots t- <= t+ of |x + t s| = radius."""
    a, b = la.dot(s, s), la.dot(x, s)
    c = la.dot(x, x) - radius ** 2
    d = math.sqrt(max(b * b - a * c, 0.0))
    q = -(b + math.copysign(d, b))
    t1, t2 = q / a, c / q if q != 0.0 else 0.0
    return min(t1, t2), max(t1, t2)


class _Model:
    """The scaled quadratic model q(p) = |J_h p|^2 / 2 + g_h . p + diag_h . p^2 / 2."""

    def __init__(self, jac_h, g_h, diag_h):
        self.jac_h, self.g_h, self.diag_h = jac_h, g_h, diag_h

    def value(self, p):
        """Return q(p)."""
        jp = la.mat_vec(self.jac_h, p)
        return 0.5 * la.dot(jp, jp) + la.dot(self.g_h, p) + 0.5 * la.dot(self.diag_h, p * p)

    def along(self, s, p0, lo, hi):
        """Return (t, q) minimising q(p0 + t s) over lo <= t <= hi."""
        js, jp = la.mat_vec(self.jac_h, s), la.mat_vec(self.jac_h, p0)
        a = 0.5 * (la.dot(js, js) + la.dot(self.diag_h, s * s))
        b = la.dot(js, jp) + la.dot(self.g_h, s) + la.dot(self.diag_h, s * p0)
        c = self.value(p0)
        ts = [lo, hi]
        if a > 0.0 and lo < -b / (2.0 * a) < hi:
            ts.append(-b / (2.0 * a))
        qs = [(a * t + b) * t + c for t in ts]
        k = int(np.argmin(qs))
        return ts[k], qs[k]


def _trust_step(s, v, uf, radius, alpha):
    """
    Return (p, alpha): the minimiser of |J p + f| over |p| <= radius, from J's SVD.

    ``s``, ``v`` and ``uf`` = U^T f are the SVD of the (augmented) scaled
    Jacobian. The Gauss-Newton step is taken when it fits; otherwise the
    Levenberg-Marquardt parameter alpha with |p(alpha)| = radius (to 1 %) is
    found by Moré's safeguarded Newton iteration, from the last step's alpha.
    """
    n = s.size
    suf = s * uf

    def phi(a):
        den = s ** 2 + a
        p_norm = la.norm(suf / den)
        return p_norm - radius, -la.dot(suf ** 2, 1.0 / den ** 3) / p_norm

    full = s[-1] > la.EPS * n * s[0] if s[0] > 0.0 else False
    if full:
        p = -la.mat_vec(v, uf / s)
        if la.norm(p) <= radius:
            return p, 0.0
        f0, df0 = phi(0.0)
        low = -f0 / df0
    else:
        low = 0.0
    high = la.norm(suf) / radius
    if not full and alpha == 0.0:
        alpha = None
    for _it in range(10):
        if alpha is None or not low <= alpha <= high:
            alpha = max(0.001 * high, math.sqrt(low * high))
        f, df = phi(alpha)
        if f < 0.0:
            high = alpha
        ratio = f / df
        low = max(low, alpha - ratio)
        alpha -= (f + radius) * ratio / radius
        if abs(f) < 0.01 * radius:
            break
    p = -la.mat_vec(v, suf / (s ** 2 + alpha))
    return p * (radius / la.norm(p)), alpha


def _choose(x, model, p, p_h, d, radius, lb, ub, theta):
    """
    Return (step, scaled step, predicted reduction) of the trust-region step ``p``.

    A step inside the box is taken; one that leaves it is cut short of the
    bound (by theta), and the better by the model of it, of its reflection
    at the bound and of the scaled gradient step is taken.
    """
    if np.all((x + p >= lb) & (x + p <= ub)):
        return p, p_h, -model.value(p_h)
    stride, hits = _to_bound(x, p, lb, ub)
    r_h = np.where(hits != 0.0, -p_h, p_h)
    p_h, p = p_h * stride, p * stride
    candidates = []
    _low, to_tr = _to_sphere(p_h, r_h, radius)
    to_b, _ = _to_bound(x + p, d * r_h, lb, ub)
    r_stride = min(to_b, to_tr)
    if r_stride > 0.0:
        lo = (1.0 - theta) * stride / r_stride
        hi = theta * to_b if to_b <= to_tr else to_tr
        if lo <= hi:
            t, q = model.along(r_h, p_h, lo, hi)
            candidates.append((q, p_h + t * r_h))
    candidates.insert(0, (model.value(theta * p_h), theta * p_h))
    ag_h = -model.g_h
    g_norm = la.norm(ag_h)
    if g_norm > 0.0:
        to_tr = radius / g_norm
        to_b, _ = _to_bound(x, d * ag_h, lb, ub)
        t, q = model.along(ag_h, np.zeros_like(ag_h), 0.0,
                           theta * to_b if to_b < to_tr else to_tr)
        candidates.append((q, t * ag_h))
    q, step_h = min(candidates, key=lambda c: c[0])
    return d * step_h, step_h, -q


def _radius(radius, actual, predicted, step_norm, on_edge):
    """Return (the next trust radius, the ratio of actual to predicted reduction)."""
    if predicted > 0.0:
        ratio = actual / predicted
    else:
        ratio = 1.0 if actual == predicted == 0.0 else 0.0
    if ratio < 0.25:
        radius = 0.25 * step_norm
    elif ratio > 0.75 and on_edge:
        radius *= 2.0
    return radius, ratio


def least_squares(fun, x0, lb, ub, diff_step, ftol=1e-8, xtol=1e-8, gtol=1e-8,
                  max_nfev=None, x_scale=1.0):
    """
    Return the bounded local least-squares fit of ``fun`` from ``x0`` (fields as scipy's).

    Parameters
    ----------
    fun : callable
        x -> the residual vector.
    x0 : numpy.ndarray
        The starting point (moved strictly inside the box).
    lb, ub : numpy.ndarray
        The bounds.
    diff_step : float
        Relative step of the forward differences.
    ftol, xtol, gtol : float
        Stop when the cost falls by less than ftol of itself (with the model
        agreeing), the step is below xtol (xtol + |x|), or the scaled
        gradient's largest entry is below gtol.
    max_nfev : int or None
        Most evaluations of steps (None: 100 per parameter).
    x_scale : float or numpy.ndarray
        Characteristic scale of each variable.

    """
    lb = np.broadcast_to(np.asarray(lb, dtype=float), np.shape(x0)).copy()
    ub = np.broadcast_to(np.asarray(ub, dtype=float), np.shape(x0)).copy()
    x = _feasible(np.asarray(x0, dtype=float), lb, ub, 1e-10)
    n = x.size
    scale = np.broadcast_to(np.asarray(x_scale, dtype=float), x.shape)
    max_nfev = max_nfev or 100 * n
    f = np.asarray(fun(x), dtype=float)
    nfev, njev = 1, 1
    if not np.all(np.isfinite(f)):
        raise ValueError('Residuals are not finite in the initial point.')
    cost = 0.5 * la.dot(f, f)
    jac = _jacobian(fun, x, f, lb, ub, diff_step)
    g = np.einsum('ki,k->i', jac, f)
    radius = la.norm(x / scale) or 1.0
    alpha, status = 0.0, None
    while True:
        v, dv = _scaling(x, g, lb, ub)
        g_norm = float(np.max(np.abs(g * v))) if n else 0.0
        if g_norm < gtol:
            status = 1
        if status is not None or nfev >= max_nfev:
            break
        d = np.sqrt(v) * scale
        diag_h = g * dv * scale
        jac_h = jac * d[None, :]
        model = _Model(jac_h, d * g, diag_h)
        aug = np.vstack([jac_h, np.diag(np.sqrt(diag_h))])
        s, vv, uf = la.svd(aug, np.concatenate([f, np.zeros(n)]))
        theta = max(0.995, 1.0 - g_norm)
        actual = -1.0
        while actual <= 0.0 and nfev < max_nfev:
            p_h, alpha = _trust_step(s, vv, uf, radius, alpha)
            step, step_h, predicted = _choose(x, model, d * p_h, p_h, d, radius, lb, ub, theta)
            x_new = _feasible(x + step, lb, ub, 0.0)
            f_new = np.asarray(fun(x_new), dtype=float)
            nfev += 1
            step_h_norm = la.norm(step_h)
            if not np.all(np.isfinite(f_new)):
                radius = 0.25 * step_h_norm
                continue
            cost_new = 0.5 * la.dot(f_new, f_new)
            actual = cost - cost_new
            new_radius, ratio = _radius(radius, actual, predicted, step_h_norm,
                                        step_h_norm > 0.95 * radius)
            step_norm = la.norm(step)
            ftol_ok = actual < ftol * cost and ratio > 0.25
            xtol_ok = step_norm < xtol * (xtol + la.norm(x))
            status = 4 if ftol_ok and xtol_ok else 2 if ftol_ok else 3 if xtol_ok else None
            if status is not None:
                break
            alpha *= radius / new_radius if new_radius > 0.0 else 1.0
            radius = new_radius
        if actual > 0.0:
            x, f, cost = x_new, f_new, cost_new
            jac = _jacobian(fun, x, f, lb, ub, diff_step)
            njev += 1
            g = np.einsum('ki,k->i', jac, f)
    status = 0 if status is None else status
    v, _ = _scaling(x, g, lb, ub)
    tol = xtol * np.maximum(1.0, np.abs(x))
    active = np.where(x - lb <= tol, -1, np.where(ub - x <= tol, 1, 0))
    return OptimizeResult(x=x, cost=cost, fun=f, jac=jac, grad=g,
                          optimality=float(np.max(np.abs(g * v))) if n else 0.0,
                          active_mask=active, nfev=nfev, njev=njev, status=status,
                          message=MESSAGES[status], success=status > 0)
