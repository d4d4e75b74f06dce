"""
The kernel's scalar friction solvers against the box-LCP conditions and the array LCP.

The fast paths of kernel.step (_box1 for one friction element, _box2 for
two, the exp-free stick bound _mu_lower) must give exactly what the general
array solver (_friction_lcp, still used for three or four elements) gives,
and that must be a solution of the box LCP: for each element, either stuck
(|p| <= limit, velocity after the impulse ~ 0) or sliding (p = +-limit with
the velocity not reversed by it).
"""
import math

import numpy as np

from leadscrew_sim.core.engine import friction as F, layout as L, lcp

RNG_SEED = 20261123


def _element_rows(rng):
    """Jacobian rows of the 4 friction elements and the inverse masses, random geometry."""
    lam = rng.uniform(0.02, 0.6)
    r_m = rng.uniform(0.002, 0.02)
    rc, sl = r_m * math.cos(lam), math.sin(lam)
    minv = 1.0 / np.array([rng.uniform(1e-6, 1e-3), rng.uniform(1e-6, 1e-3),
                           rng.uniform(0.05, 200.0), rng.uniform(0.01, 5.0)])
    rows = np.array([[0, rc, sl, 0], [0, rc, 0, sl], [0, 1, 0, 0], [0, 0, 1, 0]], float)
    return rows, minv


def _delassus(rows, minv, ids):
    """W[a, b] = J_a M^-1 J_b^T, summed as the array kernel did (i = 0..3)."""
    n = len(ids)
    W = np.zeros((L.MAXE, L.MAXE))
    for a in range(n):
        for b in range(n):
            w = 0.0
            for i in range(4):
                w += rows[ids[a], i] * rows[ids[b], i] * minv[i]
            W[a, b] = w
    return W


def _array_lcp(W, v0, lim, mode):
    n = len(v0)
    p = np.zeros(L.MAXE)
    A = np.zeros((L.MAXE, L.MAXE))
    r = np.zeros(L.MAXE)
    idx = np.zeros(L.MAXE, np.int64)
    trial = np.zeros(L.MAXE, np.int64)
    mode_a = np.zeros(L.MAXE, np.int64)
    mode_a[:n] = mode
    v = np.zeros(L.MAXE)
    v[:n] = v0
    lm = np.zeros(L.MAXE)
    lm[:n] = lim
    ok = lcp._friction_lcp(W, v, lm, mode_a, n, p, A, r, idx, trial)
    return ok, p[:n].copy(), mode_a[:n].copy()


def _assert_box_lcp(W, v0, lim, p):
    """Check the box-LCP conditions themselves (the oracle, independent of any solver)."""
    n = len(v0)
    v = v0 + W[:n, :n] @ p
    for j in range(n):
        scale = abs(v0[j]) + W[j, j] * lim[j]
        assert abs(p[j]) <= lim[j] * (1 + 1e-8)
        if abs(p[j]) < lim[j] * (1 - 1e-8):          # stuck: no sliding afterwards
            assert abs(v[j]) <= 1e-7 * scale
        elif p[j] > 0:                                # pushing at the limit: v not reversed
            assert v[j] <= 1e-7 * scale
        else:
            assert v[j] >= -1e-7 * scale


def _problem(rng, n):
    rows, minv = _element_rows(rng)
    ids = np.sort(rng.choice(4, size=n, replace=False))
    W = _delassus(rows, minv, ids)
    wd = np.array([W[j, j] for j in range(n)])
    lim = rng.uniform(0.0, 1.0, n) ** 3 * rng.uniform(1e-6, 1e-2)
    # pre-impulse velocities from about what the limits can stop, so every mode occurs
    v0 = rng.normal(0.0, 1.0, n) * wd * lim * rng.choice([0.3, 1.0, 3.0])
    mode = rng.integers(-1, 2, n)
    return W, v0, lim, mode


def test_box1_equals_array_lcp_and_solves_it():
    rng = np.random.default_rng(RNG_SEED)
    for _ in range(3000):
        W, v0, lim, mode = _problem(rng, 1)
        ok, p_ref, m_ref = _array_lcp(W, v0, lim, mode)
        p, m, searched = lcp._box1(W[0, 0], v0[0], lim[0], mode[0])
        assert ok
        assert p == p_ref[0] and m == m_ref[0]
        _assert_box_lcp(W, v0, lim, np.array([p]))


def test_box2_equals_array_lcp_and_solves_it():
    rng = np.random.default_rng(RNG_SEED + 1)
    modes_seen = set()
    for _ in range(3000):
        W, v0, lim, mode = _problem(rng, 2)
        ok, p_ref, m_ref = _array_lcp(W, v0, lim, mode)
        p1, p2, m1, m2, searched = lcp._box2(W[0, 0], W[0, 1], W[1, 1], v0[0], v0[1],
                                             lim[0], lim[1], mode[0], mode[1])
        assert ok
        assert (p1, p2) == (p_ref[0], p_ref[1]) and (m1, m2) == (m_ref[0], m_ref[1])
        _assert_box_lcp(W, v0, lim, np.array([p1, p2]))
        modes_seen.add((m1, m2))
    assert len(modes_seen) == 9          # every stick/slip combination was exercised


def test_stick_bound_never_exceeds_exact_limit():
    """The stick bound (no exp, h/cos margin) stays below the exact limit."""
    rng = np.random.default_rng(RNG_SEED + 2)
    for _ in range(20000):
        muk = rng.uniform(0.0, 0.6)
        drop = rng.choice([0.0, 1.0, -1.0]) * rng.uniform(0.0, 0.4) * rng.choice([1.0, 1e-6])
        muv = rng.choice([0.0, rng.uniform(-0.5, 0.5)])
        vst = 10.0 ** rng.uniform(-5, -1)
        dst = rng.choice([1.0, rng.uniform(0.3, 3.0)])
        v = rng.choice([0.0, 1.0, -1.0]) * 10.0 ** rng.uniform(-18, 0) * vst * 3
        h, cl, na = 10.0 ** rng.uniform(-6, -3), rng.uniform(0.8, 1.0), 10.0 ** rng.uniform(-3, 5)
        fc = F.friction_constants(_pvec(muk, muk + drop, vst, dst, muv))
        hcl = h / cl
        exact = F._thread_limit(na, v, fc, hcl)
        lim, bound = F._thread_limits(na, 0, v, fc, hcl, hcl * (1.0 - 1e-14))
        if lim < 0.0:                     # the bound stands in for the limit
            assert 0.0 < bound <= exact
        else:                             # no usable bound: the exact limit itself
            assert lim == exact


def test_stribeck_cut_is_exact():
    """Skipping the Stribeck term above zcut gives the bits of the full formula."""
    rng = np.random.default_rng(RNG_SEED + 3)
    for _ in range(20000):
        muk = rng.uniform(1e-3, 0.6)
        mus = muk + rng.uniform(-0.5, 1.0) * muk
        drop = mus - muk                     # as the kernel forms it
        dst = rng.choice([1.0, rng.uniform(0.3, 3.0)])
        vst = 10.0 ** rng.uniform(-5, -1)
        muv = rng.uniform(0.0, 0.5)
        zcut = F._stribeck_cut(muk, drop, dst)          # in units of |v| / v_st
        v = vst * zcut * rng.uniform(0.5, 3.0)          # both sides of the cut
        P = _pvec(muk, mus, vst, dst, muv)
        assert F._mu(F.friction_constants(P), v) == F.mu_apparent(P, v)


def _pvec(muk, mus, vst, dst, muv):
    P = np.zeros(L.NP)
    F.pack_apparent(P, mus, muk, muv, vst, dst)
    return P
