"""
Exact solvers of the box-constrained friction LCP of one substep, compiled.

Each friction element j has a velocity v_j = v0_j + sum_k W_jk p_k after the
impulses p, and a limit lim_j >= 0: either |p_j| <= lim_j with v_j = 0 (stuck,
mode 0) or p_j = mode_j lim_j with mode_j v_j <= 0 (sliding, mode -1 or +1).
_solve_free and _friction_lcp solve it on arrays for any n <= MAXE;
_box1 (n = 1) and _solve2/_box2 (n = 2) are scalar versions with the same
arithmetic, so all give bit-identical impulses (test/core/test_kernel_lcp.py).
"""
from ._jit import kernel_jit


@kernel_jit
def _solve_free(W, v0, lim, mode, n, p, A, r, idx):
    """Solve for impulses given a stick/slip mode per element; True if consistent."""
    nf = 0
    for j in range(n):
        if mode[j] != 0:
            p[j] = mode[j] * lim[j]
        else:
            p[j] = 0.0
            nf += 1
    if nf > 0:
        m = 0
        for j in range(n):
            if mode[j] == 0:
                idx[m] = j
                m += 1
        for a in range(m):
            ja = idx[a]
            rhs = -v0[ja]
            for j in range(n):
                if mode[j] != 0:
                    rhs -= W[ja, j] * p[j]
            r[a] = rhs
            for b in range(m):
                A[a, b] = W[ja, idx[b]]
            A[a, a] += 1e-12 * W[ja, ja] + 1e-300
        # Gaussian elimination with partial pivoting (m <= 4)
        for c in range(m):
            piv = c
            for rr in range(c + 1, m):
                if abs(A[rr, c]) > abs(A[piv, c]):
                    piv = rr
            if piv != c:
                for cc in range(m):
                    tmp = A[c, cc]
                    A[c, cc] = A[piv, cc]
                    A[piv, cc] = tmp
                tmp = r[c]
                r[c] = r[piv]
                r[piv] = tmp
            for rr in range(c + 1, m):
                fct = A[rr, c] / A[c, c]
                for cc in range(c, m):
                    A[rr, cc] -= fct * A[c, cc]
                r[rr] -= fct * r[c]
        for c in range(m - 1, -1, -1):
            s = r[c]
            for cc in range(c + 1, m):
                s -= A[c, cc] * r[cc]
            r[c] = s / A[c, c]
        for a in range(m):
            p[idx[a]] = r[a]
    # consistency check
    for j in range(n):
        vj = v0[j]
        for k in range(n):
            vj += W[j, k] * p[k]
        tol = 1e-9 * (abs(v0[j]) + W[j, j] * lim[j]) + 1e-300
        if mode[j] == 0:
            if abs(p[j]) > lim[j] * (1.0 + 1e-9):
                return False
        elif mode[j] * vj > tol:
            return False
    return True


@kernel_jit
def _friction_lcp(W, v0, lim, mode, n, p, A, r, idx, trial):
    """Box LCP of the friction impulses: warm start, else exhaustive modes."""
    if _solve_free(W, v0, lim, mode, n, p, A, r, idx):
        return True
    total = 1
    for j in range(n):
        total *= 3
    for code in range(total):
        c = code
        for j in range(n):
            trial[j] = (c % 3) - 1
            c //= 3
        if _solve_free(W, v0, lim, trial, n, p, A, r, idx):
            for j in range(n):
                mode[j] = trial[j]
            return True
    return False


@kernel_jit
def _box1(w, v0, lim, mode):
    """
    One friction element: (impulse, mode, searched) of the scalar box LCP.

    The same arithmetic as _solve_free/_friction_lcp with n = 1: the warm-start
    mode first, then the modes -1, 0, +1 in that order.
    """
    searched = False
    for attempt in range(4):
        md = mode if attempt == 0 else attempt - 2
        if md != 0:
            p = md * lim
        else:
            p = -v0 / (w + (1e-12 * w + 1e-300))
        if md == 0:
            ok = abs(p) <= lim * (1.0 + 1e-9)
        else:
            tol = 1e-9 * (abs(v0) + w * lim) + 1e-300
            ok = md * (v0 + w * p) <= tol
        if ok:
            return p, md, searched
        searched = True
    return lim, mode, True


@kernel_jit
def _solve2(w11, w12, w22, v1, v2, l1, l2, m1, m2):
    """
    Two friction elements in the given modes: (p1, p2, consistent).

    The same arithmetic as _solve_free with n = 2 (regularised diagonal,
    partial pivoting), so both give bit-identical impulses.
    """
    p1 = m1 * l1 if m1 != 0 else 0.0
    p2 = m2 * l2 if m2 != 0 else 0.0
    if m1 == 0 and m2 == 0:
        a00 = w11 + (1e-12 * w11 + 1e-300)
        a01 = w12
        a10 = w12
        a11 = w22 + (1e-12 * w22 + 1e-300)
        r0 = -v1
        r1 = -v2
        if abs(a10) > abs(a00):
            a00, a10 = a10, a00
            a01, a11 = a11, a01
            r0, r1 = r1, r0
        fct = a10 / a00
        a11 -= fct * a01
        r1 -= fct * r0
        p2 = r1 / a11
        p1 = (r0 - a01 * p2) / a00
    elif m1 == 0:
        p1 = (-v1 - w12 * p2) / (w11 + (1e-12 * w11 + 1e-300))
    elif m2 == 0:
        p2 = (-v2 - w12 * p1) / (w22 + (1e-12 * w22 + 1e-300))
    if m1 == 0:
        if abs(p1) > l1 * (1.0 + 1e-9):
            return p1, p2, False
    elif m1 * (v1 + w11 * p1 + w12 * p2) > 1e-9 * (abs(v1) + w11 * l1) + 1e-300:
        return p1, p2, False
    if m2 == 0:
        if abs(p2) > l2 * (1.0 + 1e-9):
            return p1, p2, False
    elif m2 * (v2 + w12 * p1 + w22 * p2) > 1e-9 * (abs(v2) + w22 * l2) + 1e-300:
        return p1, p2, False
    return p1, p2, True


@kernel_jit
def _box2(w11, w12, w22, v1, v2, l1, l2, m1, m2):
    """Two friction elements: (p1, p2, mode1, mode2, searched), as _friction_lcp."""
    p1, p2, ok = _solve2(w11, w12, w22, v1, v2, l1, l2, m1, m2)
    if ok:
        return p1, p2, m1, m2, False
    for code in range(9):
        t1 = code % 3 - 1
        t2 = code // 3 - 1
        p1, p2, ok = _solve2(w11, w12, w22, v1, v2, l1, l2, t1, t2)
        if ok:
            return p1, p2, t1, t2, True
    return p1, p2, m1, m2, True
