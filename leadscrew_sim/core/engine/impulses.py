"""
The friction impulses of a substep (a stage of kernel._steps), compiled.

friction_impulses solves the thread, bearing and guide friction of one
substep: one active element in closed form, a pair by _impulses_pair, more
by _impulses_general (the box LCP of lcp). Conventions as in
:mod:`.stages`.
"""
from ._jit import kernel_jit
from .stages import inline_jit
from .friction import _thread_limit, _thread_limits
from .lcp import _box1, _box2, _friction_lcp, _solve2, _solve_free
from .layout import (
    IWK_EID, IWK_IDX, IWK_MODE, IWK_TRIAL, MAXE, WK_A, WK_INT, WK_LCP, WK_LIM, WK_P, WK_R,
    WK_V0, WK_W,
)


# Friction impulses ---------------------------------------------------------------------------

@inline_jit
def friction_impulses(dq0, va0, vb0, dq, va, vb, load_a, load_b, faprev, mode_a, mode_b,
                      mode_c, mode_g, lc, wk, iwk):
    """
    Solve the friction impulses of a substep and apply them to the free velocities.

    dq0 [rad/s], va0, vb0 [m/s]: screw rate and nut velocities at the substep
    start (they set the friction law's sliding velocities); dq, va, vb: the
    same after the smooth forces; load_a, load_b: flank loads of the threads,
    flo + fup [N]; faprev: axial thread force of the last substep [N] (collar
    limit); mode_*: the elements' warm-start modes; lc: friction_setup; wk,
    iwk: the workspace of the general LCP. Returns (dq, va, vb, imp_a, imp_b,
    imp_c, imp_g, mode_a, mode_b, mode_c, mode_g, nact, a_alone, searched):
    velocities after friction, impulses, modes (the next warm start), number
    of active elements, thread A the only one, the warm start was not the
    solution. One or two active elements are solved by the scalar _box1/_box2,
    three or four by the general box LCP; all give the same impulses.
    """
    (rc, sl, fc, h, hcl, hcl_lo, ts0, mu_r_col, lim_g, mi_s, mi_a, mi_b, w_aa, w_ac, w_ag,
     nrecip_w_aa, w_table) = lc
    # friction limits (0: inactive; -1: stuck thread whose limit is not computed yet, with
    # lo_a, lo_b its exp-free lower bound)
    vs_a = rc * dq0 + sl * va0
    vs_b = rc * dq0 + sl * vb0
    lim_a, lo_a = _thread_limits(load_a, mode_a, vs_a, fc, hcl, hcl_lo)
    lim_b, lo_b = _thread_limits(load_b, mode_b, vs_b, fc, hcl, hcl_lo)
    lim_c = h * (ts0 + mu_r_col * abs(faprev))
    nact = int(lim_a != 0.0) + int(lim_b != 0.0) + int(lim_c > 0.0) + int(lim_g > 0.0)
    imp_a = imp_b = imp_c = imp_g = 0.0
    searched = False
    a_alone = nact == 1 and lim_a != 0.0
    if a_alone:   # thread A alone, the common case, without the tables of _impulses_pair
        vfree_a = rc * dq + sl * va   # its sliding velocity before friction [m/s]
        if lim_a < 0.0:   # stuck warm start: the stick impulse of _box1, on the bound
            imp_a = vfree_a * nrecip_w_aa
            if abs(imp_a) > lo_a * (1.0 + 1e-9):
                lim_a = _thread_limit(load_a, vs_a, fc, hcl)
                imp_a, mode_a, searched = _box1(w_aa, vfree_a, lim_a, 0)
        else:
            imp_a, mode_a, searched = _box1(w_aa, vfree_a, lim_a, mode_a)
        dq += imp_a * w_ac
        va += imp_a * w_ag
    elif nact > 0:
        lim_of = (lim_a, lim_b, lim_c, lim_g)
        mode_of = (mode_a, mode_b, mode_c, mode_g)
        if nact <= 2:
            (imp_a, imp_b, imp_c, imp_g, mode_a, mode_b, mode_c, mode_g,
             searched) = _impulses_pair(nact, lim_of, (lo_a, lo_b, lim_c, lim_g),
                                        (rc * dq + sl * va, rc * dq + sl * vb, dq, va),
                                        mode_of, load_a, load_b, vs_a, vs_b, fc, hcl, w_table)
        else:
            (imp_a, imp_b, imp_c, imp_g, mode_a, mode_b, mode_c, mode_g,
             searched) = _impulses_general(lim_of, mode_of, dq, va, vb, load_a, load_b, vs_a,
                                           vs_b, rc, sl, fc, hcl, w_table, wk, iwk)
        # element by element, in element order (adding 0 changes nothing)
        dq += rc * imp_a * mi_s
        va += sl * imp_a * mi_a
        dq += rc * imp_b * mi_s
        vb += sl * imp_b * mi_b
        dq += imp_c * mi_s
        va += imp_g * mi_a
    return (dq, va, vb, imp_a, imp_b, imp_c, imp_g, mode_a, mode_b, mode_c, mode_g, nact,
            a_alone, searched)


@inline_jit
def _impulses_pair(nact, lim_of, lo_of, vfree_of, mode_of, load_a, load_b, vs_a, vs_b, fc,
                   hcl, w_table):
    """
    Return the impulses of one or two active elements by the scalar _box1/_box2.

    nact: 1 or 2; lim_of, lo_of, vfree_of, mode_of: limits [N s] (-1: a stuck
    thread, not computed yet), their lower bounds, free sliding velocities and
    warm-start modes, indexed by element id; load_*, vs_*: flank loads [N] and
    sliding velocities [m/s] of the threads (for a limit still to compute);
    fc, hcl, w_table: as in friction_setup. Returns (imp_a, imp_b, imp_c,
    imp_g, mode_a, mode_b, mode_c, mode_g, searched).
    """
    lim_a, lim_b, lim_c, lim_g = lim_of
    mode_a, mode_b, mode_c, mode_g = mode_of
    # elements e1 < e2 (e2 = -1 if one): 0 thread A, 1 thread B, 2 bearing, 3 guide
    e1 = 0 if lim_a != 0.0 else (1 if lim_b != 0.0 else (2 if lim_c > 0.0 else 3))
    e2 = -1
    if nact == 2:
        e2 = 3 if lim_g > 0.0 else (2 if lim_c > 0.0 else 1)
    lim1 = lim_of[e1]
    vfree1 = vfree_of[e1]
    w1 = w_table[5 * e1]
    searched = False
    if nact == 1:
        # stuck warm start: the stick impulse of _box1, on the bound
        if lim1 < 0.0:
            imp1 = -vfree1 / (w1 + (1e-12 * w1 + 1e-300))
            mode1 = 0
            if abs(imp1) > lo_of[e1] * (1.0 + 1e-9):
                lim1 = _thread_limit(load_a if e1 == 0 else load_b,
                                     vs_a if e1 == 0 else vs_b, fc, hcl)
                imp1, mode1, searched = _box1(w1, vfree1, lim1, 0)
        else:
            imp1, mode1, searched = _box1(w1, vfree1, lim1, mode_of[e1])
        imp2 = 0.0
        mode2 = 0
    else:
        lim2 = lim_of[e2]
        vfree2 = vfree_of[e2]
        w2 = w_table[5 * e2]
        w12 = w_table[4 * e1 + e2]
        ok = False
        if (lim1 < 0.0 or lim2 < 0.0) and mode_of[e1] == 0 and mode_of[e2] == 0:
            imp1, imp2, ok = _solve2(w1, w12, w2, vfree1, vfree2, lo_of[e1], lo_of[e2], 0, 0)
            mode1 = 0
            mode2 = 0
        if not ok:
            if lim1 < 0.0:
                lim1 = _thread_limit(load_a if e1 == 0 else load_b,
                                     vs_a if e1 == 0 else vs_b, fc, hcl)
            if lim2 < 0.0:
                lim2 = _thread_limit(load_a if e2 == 0 else load_b,
                                     vs_a if e2 == 0 else vs_b, fc, hcl)
            imp1, imp2, mode1, mode2, searched = _box2(
                w1, w12, w2, vfree1, vfree2, lim1, lim2, mode_of[e1], mode_of[e2])
    imp_a = imp1 if e1 == 0 else 0.0
    imp_b = imp1 if e1 == 1 else (imp2 if e2 == 1 else 0.0)
    imp_c = imp1 if e1 == 2 else (imp2 if e2 == 2 else 0.0)
    imp_g = imp1 if e1 == 3 else (imp2 if e2 == 3 else 0.0)
    mode_a = mode1 if e1 == 0 else mode_a
    mode_b = mode1 if e1 == 1 else (mode2 if e2 == 1 else mode_b)
    mode_c = mode1 if e1 == 2 else (mode2 if e2 == 2 else mode_c)
    mode_g = mode1 if e1 == 3 else (mode2 if e2 == 3 else mode_g)
    return imp_a, imp_b, imp_c, imp_g, mode_a, mode_b, mode_c, mode_g, searched


@kernel_jit
def _impulses_general(lim_of, mode_of, dq, va, vb, load_a, load_b, vs_a, vs_b, rc, sl, fc,
                      hcl, w_table, wk, iwk):
    """
    Return the impulses of three or four active elements by the general box LCP.

    lim_of, mode_of: limits [N s] (-1: a stuck thread, not computed yet) and
    warm-start modes by element id; dq [rad/s], va, vb [m/s]: free velocities;
    load_*, vs_*: flank loads [N] and sliding velocities [m/s] of the threads;
    rc, sl, fc, hcl, w_table: as in friction_setup; wk, iwk: the workspace
    (lcp._solve_free: W, v0, lim, p, A, r; mode, eid the element id of each
    active slot, idx, trial). Returns (imp_a, imp_b, imp_c, imp_g, mode_a,
    mode_b, mode_c, mode_g, searched).
    """
    lim_a, lim_b, lim_c, lim_g = lim_of
    mode_a, mode_b, mode_c, mode_g = mode_of
    imp_a = imp_b = imp_c = imp_g = 0.0
    if lim_a < 0.0:
        lim_a = _thread_limit(load_a, vs_a, fc, hcl)
    if lim_b < 0.0:
        lim_b = _thread_limit(load_b, vs_b, fc, hcl)
    W = wk[WK_W:WK_V0].reshape((MAXE, MAXE))
    v0 = wk[WK_V0:WK_LIM]
    lim = wk[WK_LIM:WK_P]
    p = wk[WK_P:WK_A]
    A = wk[WK_A:WK_R].reshape((MAXE, MAXE))
    r = wk[WK_R:WK_LCP]
    mode = iwk[IWK_MODE:IWK_EID]
    eid = iwk[IWK_EID:IWK_IDX]
    idx = iwk[IWK_IDX:IWK_TRIAL]
    trial = iwk[IWK_TRIAL:WK_INT]
    nact = 0
    for e, lim_e in ((0, lim_a), (1, lim_b), (2, lim_c), (3, lim_g)):
        if lim_e > 0.0:
            eid[nact] = e
            lim[nact] = lim_e
            nact += 1
    for a in range(nact):
        ea = eid[a]
        if ea == 0:
            mode[a] = mode_a
            v0[a] = rc * dq + sl * va
        elif ea == 1:
            mode[a] = mode_b
            v0[a] = rc * dq + sl * vb
        elif ea == 2:
            mode[a] = mode_c
            v0[a] = dq
        else:
            mode[a] = mode_g
            v0[a] = va
        for b in range(nact):
            W[a, b] = w_table[4 * ea + eid[b]]
    searched = False
    if not _solve_free(W, v0, lim, mode, nact, p, A, r, idx):
        searched = True
        _friction_lcp(W, v0, lim, mode, nact, p, A, r, idx, trial)
    for a in range(nact):
        ea = eid[a]
        if ea == 0:
            mode_a = mode[a]
            imp_a = p[a]
        elif ea == 1:
            mode_b = mode[a]
            imp_b = p[a]
        elif ea == 2:
            mode_c = mode[a]
            imp_c = p[a]
        else:
            mode_g = mode[a]
            imp_g = p[a]
    return imp_a, imp_b, imp_c, imp_g, mode_a, mode_b, mode_c, mode_g, searched
