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

# Helpers that take arrays are compiled without the numba runtime (_nrt=False): they
# allocate nothing, and skipping the reference counting of their array arguments
# cut a substep from ~280 ns to ~100 ns here (bench/README.md).
try:  # numba is the accelerator (see README, "Why numba"); plain Python also works.
    from numba import njit
except ImportError:  # pragma: no cover
    def njit(*args, **kwargs):
        """Identity decorator used when numba is not installed."""
        if args and callable(args[0]):
            return args[0]
        return lambda fn: fn

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
NP = 36

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


@njit(cache=True, error_model='numpy', _nrt=False)
def mu_apparent(P, v):
    """Apparent Stribeck friction coefficient mu'(|v|), >= 0."""
    a = abs(v)
    mu = P[P_MUK] + P[P_MUV] * a
    drop = P[P_MUS] - P[P_MUK]
    if drop != 0.0:
        z = a / P[P_VST]
        if P[P_DST] != 1.0:
            z = z ** P[P_DST]
        mu += drop * math.exp(-z)
    return mu if mu > 0.0 else 0.0


@njit(cache=True, error_model='numpy', _nrt=False)
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


@njit(cache=True, error_model='numpy', _nrt=False)
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


WK_FLOAT = 104   # workspace sizes of step()
WK_INT = 16


def workspace():
    """Return the (float, int) scratch arrays that step() needs."""
    return np.zeros(WK_FLOAT), np.zeros(WK_INT, dtype=np.int64)


@njit(cache=True, error_model='numpy', _nrt=False)
def step(P, S, out, t_cmd, f_in, dt, nsub, wk, iwk):
    """
    Advance the state S by exactly dt in nsub equal substeps.

    t_cmd: commanded motor torque [N m] in the q sense; f_in: external axial
    force on nut A [N] added to the parameter one. Returns 0, or 1 if a state
    became non-finite (S is then left at the last finite substep).
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
    M = wk[0:4]
    f = wk[4:8]
    u = wk[8:12]
    un = wk[12:16]
    ub = wk[16:20]
    Jm = wk[20:36].reshape((MAXE, 4))
    W = wk[36:52].reshape((MAXE, MAXE))
    v0 = wk[52:56]
    lim = wk[56:60]
    p = wk[60:64]
    A = wk[64:80].reshape((MAXE, MAXE))
    r = wk[80:84]
    Minv = wk[84:88]
    Wfull = wk[88:104].reshape((MAXE, MAXE))
    mode = iwk[0:4]
    eid = iwk[4:8]
    idx = iwk[8:12]
    trial = iwk[12:16]
    M[0] = P[P_JM]
    M[1] = P[P_JS] + (P[P_JM] if rigid else 0.0)
    M[2] = P[P_MA]
    M[3] = P[P_MB]
    for i in range(16):
        Jm.flat[i] = 0.0
    tsat = min(max(t_cmd, -P[P_TMAX]), P[P_TMAX])
    alpha = 1.0 if P[P_TAU] <= 0.0 else 1.0 - math.exp(-h / P[P_TAU])
    fext = P[P_FEXT] + f_in
    gs = P[P_GS]
    Jm[0, 1] = rc
    Jm[0, 2] = sl
    Jm[1, 1] = rc
    Jm[1, 3] = sl
    Jm[2, 1] = 1.0
    Jm[3, 2] = 1.0
    for i in range(4):
        Minv[i] = 1.0 / M[i]
    for a in range(MAXE):
        for b in range(MAXE):
            w = 0.0
            for i in range(4):
                w += Jm[a, i] * Jm[b, i] * Minv[i]
            Wfull[a, b] = w
    for _ in range(nsub):
        qm = S[S_QM]
        q = S[S_Q]
        xa = S[S_XA]
        xb = S[S_XB]
        u[0] = S[S_WM]
        u[1] = S[S_DQ]
        u[2] = S[S_VA]
        u[3] = S[S_VB]
        te = S[S_TE] + alpha * (tsat - S[S_TE])
        for i in range(4):
            f[i] = 0.0
        damp_pow = 0.0   # damping forces x their own (pre-step) rates, for dissipation
        # motor and coupling
        if rigid:
            f[1] += te
        else:
            f[0] += te
            tcs = P[P_KC] * (qm - q)
            tcd = P[P_CC] * (u[0] - u[1])
            f[0] -= tcs + tcd
            f[1] += tcs + tcd
        # bearing and guide viscous, gravity, external force
        f[1] -= P[P_CS] * u[1]
        f[2] -= P[P_CX] * u[2]
        f[2] += fext - P[P_MA] * gs
        if ab:
            f[3] -= P[P_MB] * gs
        # end stops on nut A (unilateral, damper never pulls)
        fes_lo = 0.0
        fes_hi = 0.0
        pen = P[P_XMIN] - xa
        if pen > 0.0:
            fes_lo = max(0.0, P[P_KES] * pen - P[P_CES] * u[2])
            f[2] += fes_lo
        pen2 = xa - P[P_XMAX]
        if pen2 > 0.0:
            fes_hi = max(0.0, P[P_KES] * pen2 + P[P_CES] * u[2])
            f[2] -= fes_hi
        # thread contact of nut A
        d = xa - rt * q
        dd = u[2] - rt * u[1]
        ela = -d - hb
        eua = d - hb
        pla = 0.0
        pua = 0.0
        if ela > 0.0:
            pla = max(0.0, k * ela - c * dd)
        if eua > 0.0:
            pua = max(0.0, k * eua + c * dd)
        fna = pla - pua
        f[2] += fna
        f[1] -= rt * fna
        plb = 0.0
        pub = 0.0
        fs = 0.0
        if ab:
            db = xb - rt * q
            ddb = u[3] - rt * u[1]
            elb = -db - hb
            eub = db - hb
            if elb > 0.0:
                plb = max(0.0, k * elb - c * ddb)
            if eub > 0.0:
                pub = max(0.0, k * eub + c * ddb)
            fnb = plb - pub
            f[3] += fnb
            f[1] -= rt * fnb
            fs = P[P_FP] + P[P_KP] * (P[P_B] - (xb - xa))
            f[3] += fs
            f[2] -= fs
        # unconstrained velocity
        for i in range(4):
            un[i] = u[i]
            u[i] = u[i] + h * f[i] * Minv[i]
        # friction elements with a non-zero limit
        n = 0
        vsa = rc * un[1] + sl * un[2]
        la = h * mu_apparent(P, vsa) * (pla + pua) / cl
        if la > 0.0:
            eid[n] = 0
            lim[n] = la
            n += 1
        if ab:
            vsb = rc * un[1] + sl * un[3]
            lb = h * mu_apparent(P, vsb) * (plb + pub) / cl
            if lb > 0.0:
                eid[n] = 1
                lim[n] = lb
                n += 1
        lbr = h * (P[P_TS0] + P[P_MUC] * P[P_RCOL] * abs(S[S_FAPREV]))
        if lbr > 0.0:
            eid[n] = 2
            lim[n] = lbr
            n += 1
        lg = h * P[P_FX0]
        if lg > 0.0:
            eid[n] = 3
            lim[n] = lg
            n += 1
        for a in range(n):
            ea = eid[a]
            mode[a] = int(S[S_MODE0 + ea])
            v0[a] = 0.0
            for i in range(4):
                v0[a] += Jm[ea, i] * u[i]
            for b in range(n):
                W[a, b] = Wfull[ea, eid[b]]
        if n > 0:
            if not _solve_free(W, v0, lim, mode, n, p, A, r, idx):
                S[S_NSEARCH] += 1.0
                _friction_lcp(W, v0, lim, mode, n, p, A, r, idx, trial)
            for a in range(n):
                ea = eid[a]
                S[S_MODE0 + ea] = mode[a]
                for i in range(4):
                    u[i] += Jm[ea, i] * p[a] * Minv[i]
        if rigid:
            u[0] = u[1]
        if not ab:
            u[3] = u[2]
        # positions (symplectic Euler)
        S[S_QM] = qm + h * u[0]
        S[S_Q] = q + h * u[1]
        S[S_XA] = xa + h * u[2]
        S[S_XB] = xb + h * u[3]
        S[S_WM] = u[0]
        S[S_DQ] = u[1]
        S[S_VA] = u[2]
        S[S_VB] = u[3]
        S[S_TE] = te
        # energy bookkeeping with the mid-step velocity ub
        for i in range(4):
            ub[i] = 0.5 * (un[i] + u[i])
        S[S_WIN] += h * te * (ub[1] if rigid else ub[0])
        S[S_WEXT] += h * fext * ub[2]
        damp_pow = P[P_CS] * un[1] * ub[1] + P[P_CX] * un[2] * ub[2]
        if not rigid:
            damp_pow += P[P_CC] * (un[0] - un[1]) * (ub[0] - ub[1])
        ddb_ = ub[2] - rt * ub[1]
        if ela > 0.0:
            damp_pow += (pla - k * ela) * (-ddb_)
        if eua > 0.0:
            damp_pow += (pua - k * eua) * ddb_
        if pen > 0.0:
            damp_pow += (fes_lo - P[P_KES] * pen) * (-ub[2])
        if pen2 > 0.0:
            damp_pow += (fes_hi - P[P_KES] * pen2) * ub[2]
        if ab:
            ddbb = ub[3] - rt * ub[1]
            elb2 = -(xb - rt * q) - hb
            eub2 = (xb - rt * q) - hb
            if elb2 > 0.0:
                damp_pow += (plb - k * elb2) * (-ddbb)
            if eub2 > 0.0:
                damp_pow += (pub - k * eub2) * ddbb
        S[S_EDAMP] += h * damp_pow
        fric_pow = 0.0
        fa_thr = 0.0
        tbr = 0.0
        ffa = 0.0
        ffb = 0.0
        fg = 0.0
        if n > 0:
            for a in range(n):
                ea = eid[a]
                vb = 0.0
                for i in range(4):
                    vb += Jm[ea, i] * ub[i]
                fric_pow -= p[a] * vb
                if ea == 0:
                    ffa = p[a] / h
                elif ea == 1:
                    ffb = p[a] / h
                elif ea == 2:
                    tbr = p[a] / h
                else:
                    fg = p[a] / h
        S[S_EFRIC] += fric_pow
        fa_thr = (pla - pua) + ffa * sl
        if ab:
            fa_thr += (plb - pub) + ffb * sl
        S[S_FAPREV] = fa_thr
        S[S_T] += h
        for i in range(9):
            if not math.isfinite(S[i]):
                return 1
    # outputs of the last substep
    out[O_NLA] = pla / cl
    out[O_NUA] = pua / cl
    out[O_NLB] = plb / cl
    out[O_NUB] = pub / cl
    out[O_FFA] = ffa
    out[O_FFB] = ffb
    out[O_VSA] = rc * S[S_DQ] + sl * S[S_VA]
    out[O_VSB] = rc * S[S_DQ] + sl * S[S_VB] if ab else 0.0
    out[O_STICKA] = -1.0 if pla + pua <= 0.0 else (1.0 if S[S_MODE0] == 0 else 0.0)
    out[O_STICKB] = -1.0 if plb + pub <= 0.0 else (1.0 if S[S_MODE0 + 1] == 0 else 0.0)
    out[O_CONTA] = 1.0 if pla > 0.0 else (-1.0 if pua > 0.0 else 0.0)
    out[O_CONTB] = 1.0 if plb > 0.0 else (-1.0 if pub > 0.0 else 0.0)
    out[O_FAX] = fa_thr
    out[O_TTH] = -rt * (pla - pua + plb - pub) + rc * (ffa + ffb)
    out[O_TE] = S[S_TE]
    out[O_TBR] = tbr
    out[O_FG] = fg
    out[O_NSUB] = nsub
    return 0


REC_STATE = 10   # S[0:10] is recorded per step by run_series, then the NO outputs


@njit(cache=True, error_model='numpy', _nrt=False)
def run_series(P, S, out, torques, forces, dt, nsub, wk, iwk, rec):
    """
    Run one step per entry of torques/forces (q sense, N m and N).

    After step i, rec[i, :REC_STATE] holds S[:REC_STATE] and rec[i, REC_STATE:]
    the outputs. Returns the number of steps done (fewer on a non-finite state).
    """
    for i in range(torques.shape[0]):
        if step(P, S, out, torques[i], forces[i], dt, nsub, wk, iwk) != 0:
            return i
        for j in range(REC_STATE):
            rec[i, j] = S[j]
        for j in range(NO):
            rec[i, REC_STATE + j] = out[j]
    return torques.shape[0]
