"""
Linear algebra for the fits whose results do not depend on the BLAS kernel (no ROS, no I/O).

numpy's ``@``, ``dot``, ``linalg.norm``, ``svd``, ``pinv`` and ``lstsq`` call
OpenBLAS, whose kernel is chosen per CPU (or by ``OPENBLAS_CORETYPE``) and
sums in its own order: the same fit then ends in the last bits differently on
another machine, and a re-simulation of stick-slip is rough enough in its
parameters that a last-bit difference in a step sends the optimiser to
another point. Every sum here is taken by numpy's own reductions
(``np.sum``, ``np.einsum`` without ``optimize``), whose order is fixed, so
the same inputs give the same bits under any kernel and thread count.

The matrices of a fit are tall and narrow (m residuals by p <= a dozen
parameters): a Householder QR (:func:`qr`) brings them to p x p, and a
one-sided Jacobi rotation of that (:func:`svd`) gives the singular values
to full relative accuracy.
"""
import math

import numpy as np

EPS = float(np.finfo(float).eps)


def dot(a, b):
    """Return the inner product of two vectors."""
    return float(np.sum(np.asarray(a) * np.asarray(b)))


def norm(a):
    """Return the Euclidean norm of a vector (scaled, so no square overflows)."""
    a = np.asarray(a, dtype=float)
    big = float(np.max(np.abs(a))) if a.size else 0.0
    if big == 0.0 or not math.isfinite(big):
        return big
    s = a / big
    return big * math.sqrt(float(np.sum(s * s)))


def gram(a, b=None):
    """Return a^T b (a^T a without ``b``) of matrices with the same number of rows."""
    return np.einsum('ki,kj->ij', a, a if b is None else b)


def unit_columns(a):
    """Return (``a`` with each column scaled to unit norm, a zero one left zero; the norms)."""
    size = np.sqrt(np.sum(a * a, axis=0))
    return a / np.maximum(size, 1e-300), size


def mat_vec(a, x):
    """Return a x."""
    return np.einsum('ij,j->i', a, x)


def mat_mat(a, b):
    """Return a b."""
    return np.einsum('ij,jk->ik', a, b)


def qr(a, b=None):
    """
    Return (R, Q^T b) of the Householder QR of the m x n matrix ``a`` (m >= n).

    R is n x n upper triangular; Q^T b (of ``b``, a vector of m, or zeros
    without one) has m entries, the last m - n the part of ``b`` outside the
    columns' span.
    """
    a = np.array(a, dtype=float)
    m, n = a.shape
    qtb = np.zeros(m) if b is None else np.array(b, dtype=float)
    for k in range(min(n, m)):
        x = a[k:, k]
        alpha = norm(x)
        if alpha == 0.0:
            continue
        if x[0] > 0.0:
            alpha = -alpha
        v = np.array(x)
        v[0] -= alpha
        vv = dot(v, v)
        if vv == 0.0:
            continue
        w = np.einsum('k,kj->j', v, a[k:, k:]) * (2.0 / vv)
        a[k:, k:] -= v[:, None] * w[None, :]
        qtb[k:] -= v * (2.0 * dot(v, qtb[k:]) / vv)
        a[k + 1:, k] = 0.0
    return np.triu(a[:n, :n]), qtb


def _jacobi(a):
    """Return (U S, V) of a square matrix by one-sided Jacobi rotations of its columns."""
    a = np.array(a, dtype=float)
    n = a.shape[1]
    v = np.eye(n)
    for _sweep in range(80):
        rotated = False
        for i in range(n - 1):
            for j in range(i + 1, n):
                alpha, beta = dot(a[:, i], a[:, i]), dot(a[:, j], a[:, j])
                gamma = dot(a[:, i], a[:, j])
                if gamma == 0.0 or abs(gamma) <= EPS * math.sqrt(alpha * beta):
                    continue
                rotated = True
                zeta = (beta - alpha) / (2.0 * gamma)
                t = math.copysign(1.0, zeta) / (abs(zeta) + math.sqrt(1.0 + zeta * zeta))
                c = 1.0 / math.sqrt(1.0 + t * t)
                s = c * t
                for m in (a, v):
                    ci, cj = np.array(m[:, i]), np.array(m[:, j])
                    m[:, i], m[:, j] = c * ci - s * cj, s * ci + c * cj
        if not rotated:
            break
    return a, v


def svd(a, b=None):
    """
    Return (s, V, U^T b) of the thin SVD a = U diag(s) V^T of an m x n matrix (m >= n).

    The singular values ``s`` are in descending order; U^T b is of ``b`` (a
    vector of m; zeros without one), 0 for a zero singular value.
    """
    r, qtb = qr(a, b)
    n = r.shape[1]
    us, v = _jacobi(r)
    s = np.array([norm(us[:, k]) for k in range(n)])
    order = sorted(range(n), key=lambda k: (-s[k], k))
    s, v, us = s[order], v[:, order], us[:, order]
    utb = np.array([dot(us[:, k], qtb[:n]) / s[k] if s[k] > 0.0 else 0.0 for k in range(n)])
    return s, v, utb


def singular_values(a):
    """Return the singular values of a matrix (descending)."""
    a = np.asarray(a, dtype=float)
    return svd(a if a.shape[0] >= a.shape[1] else a.T)[0]


def lstsq(a, b):
    """Return the minimum-norm least-squares x of a x = b (rank: s > eps max(m, n) s_0)."""
    s, v, utb = svd(a, b)
    keep = s > EPS * max(a.shape) * (s[0] if s.size else 0.0)
    return mat_vec(v, np.where(keep, utb / np.where(keep, s, 1.0), 0.0))


def pinv(a, rcond):
    """Return the pseudo-inverse of a square matrix (singular values below rcond s_0 dropped)."""
    us, v = _jacobi(a)
    s = np.array([norm(us[:, k]) for k in range(us.shape[1])])
    keep = s > rcond * (float(np.max(s)) if s.size else 0.0)
    inv_s2 = np.where(keep, 1.0 / np.where(keep, s, 1.0) ** 2, 0.0)
    return mat_mat(v * inv_s2[None, :], us.T)
