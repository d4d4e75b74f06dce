"""
Fixed-step integration kernel of the lead screw model (ROS-free, numba-compiled).

Generalised coordinates, all in the "q sense" of physics.md section 3
(q = h theta, so x = r_m tan(lambda) q for every hand):
    u = [motor angle rate, screw angle rate, nut A velocity, half-nut B velocity].

One substep is semi-implicit (symplectic) Euler. Smooth forces (springs,
dampers, gravity, motor) are explicit; every Coulomb-type element (thread
friction of each nut body, screw bearing plus thrust collar, nut guide) is an
implicit velocity-level impulse bounded by its friction limit, found by solving
the small box-constrained LCP exactly. A stuck element keeps its sliding
velocity at zero to round-off, so a self-locking screw does not creep
(no tanh or ramp regularisation).
"""
import math

import numpy as np

# Functions that take arrays are compiled without the numba runtime (_nrt=False):
# they allocate nothing, and skipping the reference counting of their array
# arguments was worth ~120 ns per substep in the array kernel of stop 8.
try:  # numba is the accelerator (see README, "Why numba"); plain Python also works.
    from numba import njit
except ImportError:  # pragma: no cover
    def njit(*args, **kwargs):
        """Identity decorator used when numba is not installed."""
        if args and callable(args[0]):
            return args[0]
        return lambda fn: fn

# Every kernel function lets LLVM fuse a * b + c into one FMA instruction (only
# that: no reassociation, NaN and Inf semantics kept). It shortens the substep's
# dependency chain, about 20 % faster (bench/README.md); results stay
# bit-identical from run to run on a machine. All functions get the same flag
# because numba compiles a callee with its caller's flags.
CONTRACT = {'contract'}

# Parameter vector layout (floats) --------------------------------------------
P_RT, P_RC, P_SL, P_CL = 0, 1, 2, 3          # r_m tan(lam), r_m cos(lam), sin, cos
P_MUS, P_MUK, P_VST, P_DST, P_MUV = 4, 5, 6, 7, 8   # apparent (thread-corrected) mu'
P_B, P_K, P_C = 9, 10, 11
P_JM, P_JS, P_KC, P_CC, P_RIGID = 12, 13, 14, 15, 16
P_CS, P_TS0, P_MUC, P_RCOL = 17, 18, 19, 20
P_MA, P_MB, P_CX, P_FX0, P_GS = 21, 22, 23, 24, 25
P_KES, P_CES, P_XMIN, P_XMAX = 26, 27, 28, 29
P_TMAX, P_TAU, P_AB, P_FP, P_KP = 30, 31, 32, 33, 34
P_FEXT = 35
P_ZCUT = 36                                  # Stribeck cut-off, see _stribeck_cut
NP = 37

# State vector layout --------------------------------------------------------
S_QM, S_WM, S_Q, S_DQ, S_XA, S_VA, S_XB, S_VB, S_TE, S_T = range(10)
S_WIN, S_WEXT, S_EFRIC, S_EDAMP = 10, 11, 12, 13    # accumulated energies [J]
S_FAPREV = 14                                       # last axial thread force [N]
S_MODE0 = 15                                        # 4 warm-start friction modes
S_NSEARCH = 19                                      # LCP warm-start misses (diagnostic)
NS = 20

# Per-step output layout (values of the last substep) --------------------------
O_NLA, O_NUA, O_NLB, O_NUB = 0, 1, 2, 3       # in-plane flank normal forces [N]
O_FFA, O_FFB = 4, 5                           # thread friction force along flank [N]
O_VSA, O_VSB = 6, 7                           # sliding velocity [m/s]
O_STICKA, O_STICKB = 8, 9                     # 1 stuck, 0 sliding, -1 no load
O_CONTA, O_CONTB = 10, 11                     # 1 leading, -1 trailing, 0 backlash
O_FAX = 12                                    # axial thread force on the nut(s) [N]
O_TTH = 13                                    # thread torque on the screw [N m, q sense]
O_TE = 14                                     # applied motor torque [N m, q sense]
O_TBR = 15                                    # bearing + collar friction torque [N m, q]
O_FG = 16                                     # guide Coulomb force [N]
O_NSUB = 17
NO = 18

MAXE = 4   # friction elements: thread A, thread B, bearing/collar, guide


@njit(cache=True, error_model='numpy', fastmath=CONTRACT, _nrt=False)
def mu_apparent(P, v):
    """
    Apparent Stribeck friction coefficient mu'(|v|), >= 0, from the parameter vector.

    The plain formula of physics.md section 6; step() uses _mu, the same law
    with a bit-exact shortcut, tested against this one.
    """
    a = abs(v)
    mu = P[P_MUK] + P[P_MUV] * a
    drop = P[P_MUS] - P[P_MUK]
    if drop != 0.0:
        z = a / P[P_VST]
        if P[P_DST] != 1.0:
            z = z ** P[P_DST]
        mu += drop * math.exp(-z)
    return mu if mu > 0.0 else 0.0


@njit(cache=True, error_model='numpy', fastmath=CONTRACT, _nrt=False)
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


@njit(cache=True, error_model='numpy', fastmath=CONTRACT, _nrt=False)
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


REC_STATE = 10   # S[0:10] is recorded per step by run_series, then the NO outputs
WK_IO = 104      # workspace of step(): 104 floats for the LCP, 2 for step()'s inputs,
WK_REC = 106     # one scratch record row
WK_FLOAT = WK_REC + REC_STATE + NO
WK_INT = 16


def workspace():
    """Return the (float, int) scratch arrays that step() needs."""
    return np.zeros(WK_FLOAT), np.zeros(WK_INT, dtype=np.int64)


@njit(cache=True, error_model='numpy', fastmath=CONTRACT, _nrt=False)
def _mu(muk, muv, drop, vst, dst, zcut, v):
    """
    Apparent Stribeck coefficient mu'(|v|) >= 0 from unpacked parameters.

    The Stribeck term is skipped where it cannot change the sum: for
    |v| / v_st > zcut (see _stribeck_cut) and a sum not below mu_k, it is less
    than half an ulp of the sum, so the result is bit-identical to mu_apparent.
    """
    a = abs(v)
    mu = muk + muv * a
    if drop != 0.0:
        z = a / vst
        if z <= zcut or mu < muk:
            if dst != 1.0:
                z = z ** dst
            mu += drop * math.exp(-z)
    return mu if mu > 0.0 else 0.0


@njit(cache=True, error_model='numpy', fastmath=CONTRACT, _nrt=False)
def _mu_lower(muk, muv, drop, ivst, dst, v):
    """
    Return a lower bound of _mu(v) without exp() or division: exp(-z) >= max(0, 1 - z).

    ivst = 1 / v_st. The 2e-15 |drop| margin (9 ulp) covers the rounding of
    1 - z and of the reciprocal against that of exp(-z) in _mu.
    """
    mu = muk + muv * abs(v)
    if drop > 0.0:
        z = abs(v) * ivst
        if dst == 1.0 and z < 1.0:
            mu += drop * (1.0 - z) - 2e-15 * drop
    elif drop < 0.0:
        mu += drop + 2e-15 * drop
    return mu


@njit(cache=True, error_model='numpy', fastmath=CONTRACT, _nrt=False)
def _stribeck_cut(muk, drop, dst):
    """
    Return the |v| / v_st above which |drop| exp(-z) < mu_k 2**-54 (half an ulp of mu_k).

    37.5 > 54 ln 2 = 37.43; returns inf where no cut is safe (mu_k = 0).
    """
    if muk <= 0.0 or drop == 0.0:
        return math.inf
    zc = 37.5 + math.log(abs(drop) / muk)
    if zc <= 0.0:
        return 0.0
    return zc if dst == 1.0 else zc ** (1.0 / dst)


@njit(cache=True, error_model='numpy', fastmath=CONTRACT, _nrt=False)
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


@njit(cache=True, error_model='numpy', fastmath=CONTRACT, _nrt=False)
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


@njit(cache=True, error_model='numpy', fastmath=CONTRACT, _nrt=False)
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


@njit(cache=True, error_model='numpy', fastmath=CONTRACT, _nrt=False)
def _thread_limit(load, vs, muk, muv, drop, vst, dst, zcut, hcl):
    """Exact impulse limit [N s] of a thread: mu'(vs) load h / cos(lambda); hcl = h / cos."""
    return _mu(muk, muv, drop, vst, dst, zcut, vs) * load * hcl


@njit(cache=True, error_model='numpy', fastmath=CONTRACT, _nrt=False)
def _thread_limits(load, mode, vs, muk, muv, drop, vst, ivst, dst, zcut, hcl, hcl_lo):
    """
    Return (limit, lower bound) [N s] of a thread's friction impulse.

    A thread warm-started stuck (mode 0) gets the exp-free lower bound only,
    and limit -1 (not computed yet): the bound confirms most sticks, with the
    very impulse of the exact solve. No load: (0, 0), the thread is inactive.
    """
    if load <= 0.0:
        return 0.0, 0.0
    if mode == 0:
        lo = _mu_lower(muk, muv, drop, ivst, dst, vs) * load * hcl_lo
        if lo > 0.0:
            return -1.0, lo
    return _thread_limit(load, vs, muk, muv, drop, vst, dst, zcut, hcl), 0.0


@njit(cache=True, error_model='numpy', fastmath=CONTRACT, _nrt=False)
def _flank_forces(gap, gap_rate, hb, k, c):
    """
    Return (lower, upper) in-plane flank forces [N] and penetrations [m] of a nut body.

    gap = x - r_m tan(lambda) q [m], gap_rate its rate [m/s], hb half the
    backlash [m]: compliant flanks (k [N/m], c [N s/m]) that never pull.
    """
    el = -gap - hb
    eu = gap - hb
    pl = 0.0
    pu = 0.0
    if el > 0.0:
        pl = max(0.0, k * el - c * gap_rate)
    if eu > 0.0:
        pu = max(0.0, k * eu + c * gap_rate)
    return pl, pu, el, eu


@njit(cache=True, error_model='numpy', fastmath=CONTRACT, _nrt=False)
def _steps(P, S, out, torques, forces, dt, nsub, wk, iwk, rec):
    """
    Advance S by one step of dt (nsub equal substeps) per entry of torques/forces.

    torques: commanded motor torques [N m] in the q sense; forces: external
    axial forces on nut A [N] added to the parameter one. After step i, out
    holds its outputs and rec[i] = S[:REC_STATE] + out. Returns
    the number of steps done; fewer if a state became non-finite, with S and
    out as they were before the failing step.

    Parameters are unpacked once per call and the state lives in local scalars
    within a step. One or two active friction elements are solved by the
    scalar _box1/_box2, three or four by the general box LCP on the workspace
    arrays; all give the same impulses (test/test_kernel_lcp.py).
    """
    h = dt / nsub
    rigid = P[P_RIGID] > 0.5
    ab = P[P_AB] > 0.5
    rt = P[P_RT]
    rc = P[P_RC]
    sl = P[P_SL]
    cl = P[P_CL]
    hb = 0.5 * P[P_B]
    k = P[P_K]
    c = P[P_C]
    kc = P[P_KC]
    cc = P[P_CC]
    cs = P[P_CS]
    cx = P[P_CX]
    ma = P[P_MA]
    mb = P[P_MB]
    kes = P[P_KES]
    ces = P[P_CES]
    xmin = P[P_XMIN]
    xmax = P[P_XMAX]
    muk = P[P_MUK]
    muv = P[P_MUV]
    drop = P[P_MUS] - P[P_MUK]
    vst = P[P_VST]
    dst = P[P_DST]
    zcut = P[P_ZCUT]
    ivst = 1.0 / vst
    # Limits are mu' N h / cos(lambda); the stick bound uses h / cos(lambda) less 1e-14,
    # so its limit stays below the exact one whatever the rounding of either.
    hcl = h / cl
    hcl_lo = hcl * (1.0 - 1e-14)
    fp = P[P_FP]
    kp = P[P_KP]
    bb = P[P_B]
    ts0 = P[P_TS0]
    mcr = P[P_MUC] * P[P_RCOL]
    lg = h * P[P_FX0]
    # inverse masses; element Jacobian rows (q sense): thread A [0, rc, sl, 0],
    # thread B [0, rc, 0, sl], bearing/collar [0, 1, 0, 0], guide [0, 0, 1, 0]
    mi0 = 1.0 / P[P_JM]
    mi1 = 1.0 / (P[P_JS] + (P[P_JM] if rigid else 0.0))
    mi2 = 1.0 / ma
    mi3 = 1.0 / mb
    # Delassus matrix entries J_a M^-1 J_b^T (w13 = w23 = 0)
    w00 = rc * rc * mi1 + sl * sl * mi2
    w01 = rc * rc * mi1
    w02 = rc * mi1
    w03 = sl * mi2
    w11 = rc * rc * mi1 + sl * sl * mi3
    hmi0 = h * mi0   # velocity change per unit force in one substep [1/(kg m^2) s, 1/kg s]
    hmi1 = h * mi1
    hmi2 = h * mi2
    hmi3 = h * mi3
    niden0 = -1.0 / (w00 + (1e-12 * w00 + 1e-300))
    # the full symmetric 4 x 4 matrix, row-major, for the general LCP
    wtab = (w00, w01, w02, w03, w01, w11, w02, 0.0, w02, w02, mi1, 0.0, w03, 0.0, 0.0, mi2)
    alpha = 1.0 if P[P_TAU] <= 0.0 else 1.0 - math.exp(-h / P[P_TAU])
    gs = P[P_GS]
    for i in range(torques.shape[0]):
        tsat = min(max(torques[i], -P[P_TMAX]), P[P_TMAX])
        fext = P[P_FEXT] + forces[i]
        # state in locals
        qm = S[S_QM]
        q = S[S_Q]
        xa = S[S_XA]
        xb = S[S_XB]
        u0 = S[S_WM]
        u1 = S[S_DQ]
        u2 = S[S_VA]
        u3 = S[S_VB]
        te = S[S_TE]
        t = S[S_T]
        win = S[S_WIN]
        wext = S[S_WEXT]
        efric = S[S_EFRIC]
        edamp = S[S_EDAMP]
        faprev = S[S_FAPREV]
        md0 = int(S[S_MODE0])
        md1 = int(S[S_MODE0 + 1])
        md2 = int(S[S_MODE0 + 2])
        md3 = int(S[S_MODE0 + 3])
        nsearch = S[S_NSEARCH]
        pla = pua = plb = pub = 0.0
        pa = pb = pc = pg = 0.0
        a_in = a_ext = a_damp = a_fric = 0.0   # energy sums of the step (see below)
        for _ in range(nsub):
            te_n = te + alpha * (tsat - te)
            f0 = 0.0
            f1 = 0.0
            f2 = 0.0
            f3 = 0.0
            # motor and coupling
            if rigid:
                f1 += te_n
            else:
                f0 += te_n
                tcs = kc * (qm - q)
                tcd = cc * (u0 - u1)
                f0 -= tcs + tcd
                f1 += tcs + tcd
            # bearing and guide viscous, gravity, external force
            f1 -= cs * u1
            f2 -= cx * u2
            f2 += fext - ma * gs
            if ab:
                f3 -= mb * gs
            # end stops on nut A (unilateral, damper never pulls)
            fes_lo = 0.0
            fes_hi = 0.0
            pen = xmin - xa
            if pen > 0.0:
                fes_lo = max(0.0, kes * pen - ces * u2)
                f2 += fes_lo
            pen2 = xa - xmax
            if pen2 > 0.0:
                fes_hi = max(0.0, kes * pen2 + ces * u2)
                f2 -= fes_hi
            # thread contact of nut A
            pla, pua, ela, eua = _flank_forces(xa - rt * q, u2 - rt * u1, hb, k, c)
            fna = pla - pua
            f2 += fna
            f1 -= rt * fna
            plb = 0.0
            pub = 0.0
            elb = 0.0
            eub = 0.0
            if ab:
                plb, pub, elb, eub = _flank_forces(xb - rt * q, u3 - rt * u1, hb, k, c)
                fnb = plb - pub
                f3 += fnb
                f1 -= rt * fnb
                fs = fp + kp * (bb - (xb - xa))
                f3 += fs
                f2 -= fs
            # unconstrained velocity
            un0 = u0
            un1 = u1
            un2 = u2
            un3 = u3
            if not rigid:
                u0 = u0 + f0 * hmi0
            u1 = u1 + f1 * hmi1
            u2 = u2 + f2 * hmi2
            if ab:
                u3 = u3 + f3 * hmi3
            # friction limits of the elements (0: inactive; -1: stuck thread, bound only)
            na = pla + pua
            nb = plb + pub
            vsa = rc * un1 + sl * un2
            vsb = rc * un1 + sl * un3
            la, la_lo = _thread_limits(na, md0, vsa, muk, muv, drop, vst, ivst, dst, zcut,
                                       hcl, hcl_lo)
            lb, lb_lo = _thread_limits(nb, md1, vsb, muk, muv, drop, vst, ivst, dst, zcut,
                                       hcl, hcl_lo)
            lbr = h * (ts0 + mcr * abs(faprev))
            n = (la != 0.0) + (lb != 0.0) + (lbr > 0.0) + (lg > 0.0)
            pa = pb = pc = pg = 0.0   # impulses of thread A, thread B, bearing, guide
            a_only = n == 1 and la != 0.0
            if a_only:   # thread A alone, the common case, without the tables below
                vv = rc * u1 + sl * u2
                srch = False
                if la < 0.0:   # stuck warm start: the stick impulse of _box1, on the bound
                    pa = vv * niden0
                    if abs(pa) > la_lo * (1.0 + 1e-9):
                        la = _thread_limit(na, vsa, muk, muv, drop, vst, dst, zcut, hcl)
                        pa, md0, srch = _box1(w00, vv, la, 0)
                else:
                    pa, md0, srch = _box1(w00, vv, la, md0)
                if srch:
                    nsearch += 1.0
            elif 0 < n <= 2:
                # elements e1 < e2 (e2 = -1 if one): 0 thread A, 1 thread B, 2 bearing, 3 guide
                lims = (la, lb, lbr, lg)
                los = (la_lo, lb_lo, lbr, lg)
                vels = (rc * u1 + sl * u2, rc * u1 + sl * u3, u1, u2)
                modes = (md0, md1, md2, md3)
                e1 = 0 if la != 0.0 else (1 if lb != 0.0 else (2 if lbr > 0.0 else 3))
                e2 = -1
                if n == 2:
                    e2 = 3 if lg > 0.0 else (2 if lbr > 0.0 else 1)
                l1 = lims[e1]
                v1 = vels[e1]
                w1 = wtab[5 * e1]
                srch = False
                if n == 1:
                    if l1 < 0.0:   # stuck warm start: the stick impulse of _box1, on the bound
                        p1 = -v1 / (w1 + (1e-12 * w1 + 1e-300))
                        m1 = 0
                        if abs(p1) > los[e1] * (1.0 + 1e-9):
                            l1 = _thread_limit(na if e1 == 0 else nb, vsa if e1 == 0 else vsb,
                                               muk, muv, drop, vst, dst, zcut, hcl)
                            p1, m1, srch = _box1(w1, v1, l1, 0)
                    else:
                        p1, m1, srch = _box1(w1, v1, l1, modes[e1])
                    p2 = 0.0
                    m2 = 0
                else:
                    l2 = lims[e2]
                    v2 = vels[e2]
                    w2 = wtab[5 * e2]
                    w12 = wtab[4 * e1 + e2]
                    ok = False
                    if (l1 < 0.0 or l2 < 0.0) and modes[e1] == 0 and modes[e2] == 0:
                        p1, p2, ok = _solve2(w1, w12, w2, v1, v2, los[e1], los[e2], 0, 0)
                        m1 = 0
                        m2 = 0
                    if not ok:
                        if l1 < 0.0:
                            l1 = _thread_limit(na if e1 == 0 else nb, vsa if e1 == 0 else vsb,
                                               muk, muv, drop, vst, dst, zcut, hcl)
                        if l2 < 0.0:
                            l2 = _thread_limit(na if e2 == 0 else nb, vsa if e2 == 0 else vsb,
                                               muk, muv, drop, vst, dst, zcut, hcl)
                        p1, p2, m1, m2, srch = _box2(w1, w12, w2, v1, v2, l1, l2,
                                                     modes[e1], modes[e2])
                if srch:
                    nsearch += 1.0
                pa = p1 if e1 == 0 else 0.0
                pb = p1 if e1 == 1 else (p2 if e2 == 1 else 0.0)
                pc = p1 if e1 == 2 else (p2 if e2 == 2 else 0.0)
                pg = p1 if e1 == 3 else (p2 if e2 == 3 else 0.0)
                md0 = m1 if e1 == 0 else md0
                md1 = m1 if e1 == 1 else (m2 if e2 == 1 else md1)
                md2 = m1 if e1 == 2 else (m2 if e2 == 2 else md2)
                md3 = m1 if e1 == 3 else (m2 if e2 == 3 else md3)
            elif n > 2:   # the general box LCP on the workspace arrays
                if la < 0.0:
                    la = _thread_limit(na, vsa, muk, muv, drop, vst, dst, zcut, hcl)
                if lb < 0.0:
                    lb = _thread_limit(nb, vsb, muk, muv, drop, vst, dst, zcut, hcl)
                W = wk[36:52].reshape((MAXE, MAXE))
                v0 = wk[52:56]
                lim = wk[56:60]
                p = wk[60:64]
                A = wk[64:80].reshape((MAXE, MAXE))
                r = wk[80:84]
                mode = iwk[0:4]
                eid = iwk[4:8]
                idx = iwk[8:12]
                trial = iwk[12:16]
                n = 0
                for e, le in ((0, la), (1, lb), (2, lbr), (3, lg)):
                    if le > 0.0:
                        eid[n] = e
                        lim[n] = le
                        n += 1
                for a in range(n):
                    ea = eid[a]
                    if ea == 0:
                        mode[a] = md0
                        v0[a] = rc * u1 + sl * u2
                    elif ea == 1:
                        mode[a] = md1
                        v0[a] = rc * u1 + sl * u3
                    elif ea == 2:
                        mode[a] = md2
                        v0[a] = u1
                    else:
                        mode[a] = md3
                        v0[a] = u2
                    for b in range(n):
                        W[a, b] = wtab[4 * ea + eid[b]]
                if not _solve_free(W, v0, lim, mode, n, p, A, r, idx):
                    nsearch += 1.0
                    _friction_lcp(W, v0, lim, mode, n, p, A, r, idx, trial)
                for a in range(n):
                    ea = eid[a]
                    if ea == 0:
                        md0 = mode[a]
                        pa = p[a]
                    elif ea == 1:
                        md1 = mode[a]
                        pb = p[a]
                    elif ea == 2:
                        md2 = mode[a]
                        pc = p[a]
                    else:
                        md3 = mode[a]
                        pg = p[a]
            if a_only:
                u1 += pa * w02
                u2 += pa * w03
            elif n > 0:   # element by element, in element order (adding 0 changes nothing)
                u1 += rc * pa * mi1
                u2 += sl * pa * mi2
                u1 += rc * pb * mi1
                u3 += sl * pb * mi3
                u1 += pc * mi1
                u2 += pg * mi2
            if rigid:
                u0 = u1
            if not ab:
                u3 = u2
            # positions (symplectic Euler)
            qm_n = qm + h * u0
            q_n = q + h * u1
            xa_n = xa + h * u2
            xb_n = xb + h * u3
            # energy bookkeeping with the mid-step velocities (un + u) / 2, summed over the
            # step and scaled once at its end
            s0 = un0 + u0
            s1 = un1 + u1
            s2 = un2 + u2
            s3 = un3 + u3
            a_in += te_n * (s1 if rigid else s0)
            a_ext += s2
            dp = cs * un1 * s1 + cx * un2 * s2
            if not rigid:
                dp += cc * (un0 - un1) * (s0 - s1)
            ddm = s2 - rt * s1
            if ela > 0.0:
                dp -= (pla - k * ela) * ddm
            if eua > 0.0:
                dp += (pua - k * eua) * ddm
            if pen > 0.0:
                dp -= (fes_lo - kes * pen) * s2
            if pen2 > 0.0:
                dp += (fes_hi - kes * pen2) * s2
            if ab:
                ddmb = s3 - rt * s1
                if elb > 0.0:
                    dp -= (plb - k * elb) * ddmb
                if eub > 0.0:
                    dp += (pub - k * eub) * ddmb
            a_damp += dp
            if a_only:
                a_fric += pa * (rc * s1 + sl * s2)
            elif n > 0:
                a_fric += pa * (rc * s1 + sl * s2) + pb * (rc * s1 + sl * s3) + pc * s1 + pg * s2
            if mcr > 0.0:   # the next collar limit needs this substep's axial thread force
                faprev = (pla - pua) + (pa / h) * sl
                if ab:
                    faprev += (plb - pub) + (pb / h) * sl
            qm = qm_n
            q = q_n
            xa = xa_n
            xb = xb_n
            te = te_n
            t += h
        win += 0.5 * h * a_in
        wext += 0.5 * h * fext * a_ext
        edamp += 0.5 * h * a_damp
        efric -= 0.5 * a_fric
        # friction forces [N, N m] and the axial thread force of the last substep
        ffa = pa / h
        ffb = pb / h
        tbr = pc / h
        fg = pg / h
        fa_thr = (pla - pua) + ffa * sl
        if ab:
            fa_thr += (plb - pub) + ffb * sl
        faprev = fa_thr
        # A non-finite value in a position, velocity or the motor torque stays non-finite
        # in every later substep (each is updated as x + increment), so one check per step
        # finds it; S and out are then left as they were at the start of the step.
        if not (math.isfinite(qm) and math.isfinite(q) and math.isfinite(xa) and math.isfinite(xb)
                and math.isfinite(u0) and math.isfinite(u1) and math.isfinite(u2)
                and math.isfinite(u3) and math.isfinite(te)):
            return i
        # write the state back once
        S[S_QM] = qm
        S[S_WM] = u0
        S[S_Q] = q
        S[S_DQ] = u1
        S[S_XA] = xa
        S[S_VA] = u2
        S[S_XB] = xb
        S[S_VB] = u3
        S[S_TE] = te
        S[S_T] = t
        S[S_WIN] = win
        S[S_WEXT] = wext
        S[S_EFRIC] = efric
        S[S_EDAMP] = edamp
        S[S_FAPREV] = faprev
        S[S_MODE0] = md0
        S[S_MODE0 + 1] = md1
        S[S_MODE0 + 2] = md2
        S[S_MODE0 + 3] = md3
        S[S_NSEARCH] = nsearch
        # outputs of the last substep
        out[O_NLA] = pla / cl
        out[O_NUA] = pua / cl
        out[O_NLB] = plb / cl
        out[O_NUB] = pub / cl
        out[O_FFA] = ffa
        out[O_FFB] = ffb
        out[O_VSA] = rc * u1 + sl * u2
        out[O_VSB] = rc * u1 + sl * u3 if ab else 0.0
        out[O_STICKA] = -1.0 if pla + pua <= 0.0 else (1.0 if md0 == 0 else 0.0)
        out[O_STICKB] = -1.0 if plb + pub <= 0.0 else (1.0 if md1 == 0 else 0.0)
        out[O_CONTA] = 1.0 if pla > 0.0 else (-1.0 if pua > 0.0 else 0.0)
        out[O_CONTB] = 1.0 if plb > 0.0 else (-1.0 if pub > 0.0 else 0.0)
        out[O_FAX] = fa_thr
        out[O_TTH] = -rt * (pla - pua + plb - pub) + rc * (ffa + ffb)
        out[O_TE] = te
        out[O_TBR] = tbr
        out[O_FG] = fg
        out[O_NSUB] = nsub
        for j in range(REC_STATE):
            rec[i, j] = S[j]
        for j in range(NO):
            rec[i, REC_STATE + j] = out[j]
    return torques.shape[0]


@njit(cache=True, error_model='numpy', fastmath=CONTRACT, _nrt=False)
def step(P, S, out, t_cmd, f_in, dt, nsub, wk, iwk):
    """
    Advance the state S by exactly dt in nsub equal substeps.

    t_cmd: commanded motor torque [N m] in the q sense; f_in: external axial
    force on nut A [N] added to the parameter one. Returns 0, or 1 if a state
    became non-finite (S and out are then left as they were before the call).
    """
    io = wk[WK_IO:WK_IO + 2]
    io[0] = t_cmd
    io[1] = f_in
    rec = wk[WK_REC:WK_FLOAT].reshape((1, REC_STATE + NO))   # a scratch record row
    return 0 if _steps(P, S, out, io[0:1], io[1:2], dt, nsub, wk, iwk, rec) == 1 else 1


@njit(cache=True, error_model='numpy', fastmath=CONTRACT, _nrt=False)
def run_series(P, S, out, torques, forces, dt, nsub, wk, iwk, rec):
    """
    Run one step per entry of torques/forces (q sense, N m and N) in one call.

    After step i, rec[i, :REC_STATE] holds S[:REC_STATE] and rec[i, REC_STATE:]
    the outputs. Returns the number of steps done (fewer on a non-finite state).
    """
    return _steps(P, S, out, torques, forces, dt, nsub, wk, iwk, rec)
