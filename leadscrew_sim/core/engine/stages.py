"""
The stages of the kernel's step and substep (kernel._steps), compiled.

_steps keeps the state in local scalars and passes it through these
functions in order; each takes scalars (and constant tuples formed once per
call) and returns a tuple of scalars:

- constants, once per call: body_constants (bc), inverse_masses,
  friction_setup (lc), drive_constants (dc);
- step start: load_state, load_drive, held_command, take_command, torque_path;
- drive update, every drive period: drive_update;
- forces, every substep: smooth_forces (with _flank_forces);
- friction impulses, every substep: friction_impulses (with _impulses_pair
  and _impulses_general for two or more active elements);
- energy, every substep: energy_sums;
- outputs and write-back, once per step: store_state, switch_states,
  store_drive, thread_outputs, drive_outputs, sensor_outputs.

smooth_forces, friction_impulses and _impulses_pair are compiled with
inline_jit: numba inlines them into _steps, so the substep loop is one piece
of code (LLVM would keep them as calls). The others are plain kernel_jit
functions (LLVM inlines the small ones where they are called).

Conventions as in kernel._steps: angles, rates and torques in the q sense;
bodies m motor, s screw, a nut A, b half-nut B; friction elements, in this
order, a thread of nut A, b thread of half-nut B, c screw bearing plus
thrust collar, g nut guide (ids 0, 1, 2, 3); "impulse" is per substep [N s]
(bearing: [N m s]); modes are stick/slip modes (-1, 0, 1) of the box LCP.
"""
from ._jit import DISPATCHERS, JIT_OPTIONS, kernel_jit, njit
from .drive import (
    FAULT_FOLLOWING_ERROR, FAULT_NONE, FAULT_TORQUE_LIMIT, MODE_POSITION, MODE_QUICKSTOP,
    MODE_TORQUE, velocity_loop,
)
from .friction import _thread_limit, _thread_limits, friction_constants
from .lcp import _box1, _box2, _friction_lcp, _solve2, _solve_free
from .sensors import readings
from .layout import (
    IWK_EID, IWK_IDX, IWK_MODE, IWK_TRIAL, MAXE,
    O_CONTA, O_CONTB, O_DFAULT, O_DFERR, O_DMODE, O_DTCMD, O_DWREF, O_FAX, O_FFA, O_FFB, O_FG,
    O_HOME, O_JAM, O_JQ, O_JV, O_JW, O_JX, O_NLA, O_NLB, O_NSUB, O_NUA, O_NUB, O_STICKA, O_STICKB,
    O_SWMAX, O_SWMIN, O_TBR, O_TE, O_TTH, O_VSA, O_VSB,
    P_AB, P_B, P_C, P_CC, P_CES, P_CL, P_CS, P_CX, P_DFEL, P_DKP, P_DKV, P_DQSD, P_DTI, P_DTLT,
    P_DVMAX, P_EFRZ, P_EIDEAL, P_FP, P_FX0, P_GS, P_JM, P_JS, P_K, P_KC, P_KES, P_KP, P_MA,
    P_MB, P_MUC, P_RC, P_RCOL, P_RIGID, P_RT, P_SFIT, P_SFRZ, P_SIDEAL, P_SL, P_TMAX, P_TS0,
    P_XMAX, P_XMIN,
    S_CMODE, S_CQ, S_CT, S_CW, S_DFAULT, S_DFERR, S_DINT, S_DMODE, S_DPHASE, S_DQ, S_DQREF,
    S_DQS, S_DTLIM, S_DTOUT, S_DWQS, S_DWREF, S_EDAMP, S_EFRIC, S_EQ, S_EW, S_FAPREV, S_HOME,
    S_JAM, S_MODE0, S_NSEARCH, S_Q, S_QM, S_SWMAX, S_SWMIN, S_T, S_TE, S_VA, S_VB, S_VS,
    S_WEXT, S_WIN, S_WM, S_XA, S_XB, S_XS,
    WK_A, WK_INT, WK_LCP, WK_LIM, WK_P, WK_R, WK_V0, WK_W,
)


def inline_jit(fn):
    """
    Compile ``fn`` like kernel_jit, and inline its numba IR into every compiled caller.

    For the largest stages of the substep loop: as calls they would pass their
    many scalars and constant tuples through memory in every substep.
    """
    dispatcher = njit(inline='always', **JIT_OPTIONS)(fn)
    DISPATCHERS.append(dispatcher)
    return dispatcher


# Constants, once per call -----------------------------------------------------------------

@kernel_jit
def body_constants(P):
    """
    Return bc, the constants of the smooth forces and of their energy terms.

    bc = (rigid, two_nuts, rt, half_b, k, c, kc, cc, cs, cx, ma, mb, kes, ces,
    xmin, xmax, gs, f_pre, k_pre, backlash): rigid: motor and screw are one
    body; two_nuts: the anti-backlash half-nut B is simulated; rt: r_m
    tan(lambda) [m/rad]; half_b, backlash: half the backlash, the backlash [m];
    k [N/m], c [N s/m]: flank contact stiffness and damping; kc [N m/rad], cc
    [N m s/rad]: coupling; cs [N m s/rad], cx [N s/m]: bearing and guide
    viscous damping; ma, mb: masses of nut A (with payload) and half-nut B
    [kg]; kes [N/m], ces [N s/m], xmin, xmax [m]: end stops of nut A; gs: g
    sin(inclination) [m/s^2]; f_pre [N], k_pre [N/m]: anti-backlash preload
    and spring stiffness.
    """
    return (P[P_RIGID] > 0.5, P[P_AB] > 0.5, P[P_RT], 0.5 * P[P_B], P[P_K], P[P_C], P[P_KC],
            P[P_CC], P[P_CS], P[P_CX], P[P_MA], P[P_MB], P[P_KES], P[P_CES], P[P_XMIN],
            P[P_XMAX], P[P_GS], P[P_FP], P[P_KP], P[P_B])


@kernel_jit
def inverse_masses(P, rigid):
    """
    Return (mi_m, mi_s, mi_a, mi_b): inverse inertias [1/(kg m^2)] and masses [1/kg].

    Of motor, screw (with the motor if rigid), nut A (with payload), half-nut B.
    """
    mi_m = 1.0 / P[P_JM]
    mi_s = 1.0 / (P[P_JS] + (P[P_JM] if rigid else 0.0))
    mi_a = 1.0 / P[P_MA]
    mi_b = 1.0 / P[P_MB]
    return mi_m, mi_s, mi_a, mi_b


@kernel_jit
def friction_setup(P, h, mi_s, mi_a, mi_b):
    """
    Return lc, the constants of the friction impulses for substeps of h [s].

    lc = (rc, sl, fc, h, hcl, hcl_lo, ts0, mu_r_col, lim_g, mi_s, mi_a, mi_b,
    w_aa, w_ac, w_ag, nrecip_w_aa, w_table): rc: r_m cos(lambda) [m/rad]; sl:
    sin(lambda); fc: the thread friction law's constants
    (friction.friction_constants); hcl: h / cos(lambda) [s], hcl_lo the same
    less 1e-14 relative (stick bound); ts0: bearing Coulomb torque [N m];
    mu_r_col: collar mu times radius [m]; lim_g: guide impulse limit [N s];
    mi_*: inverse_masses; w_xy: Delassus entries J_x M^-1 J_y^T of the
    elements x, y; nrecip_w_aa: -1 / (regularised w_aa), the stick impulse per
    unit velocity; w_table: the full 4 x 4 Delassus matrix, row-major in
    element order.
    """
    rc = P[P_RC]
    sl = P[P_SL]
    # Limits are mu' N h / cos(lambda); the stick bound uses h / cos(lambda) less 1e-14,
    # so its limit stays below the exact one whatever the rounding of either.
    hcl = h / P[P_CL]
    hcl_lo = hcl * (1.0 - 1e-14)
    # element Jacobian rows (q sense): thread A [0, rc, sl, 0], thread B [0, rc, 0, sl],
    # bearing/collar [0, 1, 0, 0], guide [0, 0, 1, 0]; w_bg = w_cg = 0
    w_aa = rc * rc * mi_s + sl * sl * mi_a
    w_ab = rc * rc * mi_s
    w_ac = rc * mi_s
    w_ag = sl * mi_a
    w_bb = rc * rc * mi_s + sl * sl * mi_b
    nrecip_w_aa = -1.0 / (w_aa + (1e-12 * w_aa + 1e-300))
    w_table = (w_aa, w_ab, w_ac, w_ag,
               w_ab, w_bb, w_ac, 0.0,
               w_ac, w_ac, mi_s, 0.0,
               w_ag, 0.0, 0.0, mi_a)
    return (rc, sl, friction_constants(P), h, hcl, hcl_lo, P[P_TS0], P[P_MUC] * P[P_RCOL],
            h * P[P_FX0], mi_s, mi_a, mi_b, w_aa, w_ac, w_ag, nrecip_w_aa, w_table)


@kernel_jit
def drive_constants(P, td):
    """
    Return dc, the constants of the drive update for a drive period td [s].

    dc = (kp_d, kv_d, ki_d, vmax, dw_qs, fel, tlt, tmax, td): K_p [1/s], K_v
    [N m s/rad], K_v / T_i [N m/rad] (0: no integral); velocity limit [rad/s];
    quick stop rate decrement per update [rad/s]; following error limit
    [rad]; torque limit time [s]; torque saturation [N m].
    """
    ki_d = P[P_DKV] / P[P_DTI] if P[P_DTI] > 0.0 else 0.0
    return (P[P_DKP], P[P_DKV], ki_d, P[P_DVMAX], P[P_DQSD] * td, P[P_DFEL], P[P_DTLT],
            P[P_TMAX], td)


# Step start ----------------------------------------------------------------------------------

@kernel_jit
def load_state(S):
    """
    Return the mechanical state of S as scalars.

    (qm, q [rad], xa, xb [m], wm, dq [rad/s], va, vb [m/s], te [N m], t [s],
    win, wext, efric, edamp [J], faprev [N], mode_a, mode_b, mode_c, mode_g,
    nsearch): positions, rates, applied motor torque, time, energies, axial
    thread force of the last substep, warm-start modes, warm-start misses.
    """
    return (S[S_QM], S[S_Q], S[S_XA], S[S_XB], S[S_WM], S[S_DQ], S[S_VA], S[S_VB], S[S_TE],
            S[S_T], S[S_WIN], S[S_WEXT], S[S_EFRIC], S[S_EDAMP], S[S_FAPREV],
            int(S[S_MODE0]), int(S[S_MODE0 + 1]), int(S[S_MODE0 + 2]), int(S[S_MODE0 + 3]),
            S[S_NSEARCH])


@kernel_jit
def load_drive(S):
    """
    Return the drive state of S as scalars.

    (d_mode, d_qref [rad], d_int [rad], d_tout [N m], d_phase, d_fault, d_tlim
    [s], d_qs, d_wqs [rad/s], d_ferr [rad], d_wref [rad/s]): active mode and
    target, integral I, held torque command, substeps since the last update,
    latched fault, time at the torque limit, quick stop state (0 none, 1
    requested, 2 ramping or holding) and ramp, following error, velocity
    reference.
    """
    return (int(S[S_DMODE]), S[S_DQREF], S[S_DINT], S[S_DTOUT], int(S[S_DPHASE]),
            int(S[S_DFAULT]), S[S_DTLIM], int(S[S_DQS]), S[S_DWQS], S[S_DFERR], S[S_DWREF])


@kernel_jit
def held_command(S, torques, cmds, i):
    """
    Return the held command (c_mode, c_q [rad], c_w [rad/s], c_t [N m]) of step i.

    Row i of cmds, or with no rows torque mode with torques[i].
    """
    if cmds.shape[0] > 0:
        return int(cmds[i, 0]), cmds[i, 1], cmds[i, 2], cmds[i, 3]
    return MODE_TORQUE, S[S_CQ], S[S_CW], torques[i]


@kernel_jit
def take_command(c_mode, c_q, d_mode, d_qref, d_int, d_tlim, d_qs):
    """
    Let the held command take effect: a quick stop once, any other mode at once.

    c_mode, c_q: held mode and target [rad]; d_*: the drive state (load_drive).
    Returns (d_mode, d_qref, d_int, d_tlim, d_qs).
    """
    if c_mode == MODE_QUICKSTOP:
        if d_qs == 0:
            if d_mode == MODE_TORQUE:
                d_int = 0.0
                d_tlim = 0.0
            d_mode = MODE_QUICKSTOP
            d_qs = 1
    else:
        if d_mode == MODE_TORQUE and c_mode != MODE_TORQUE:   # the drive starts afresh
            d_int = 0.0
            d_tlim = 0.0
        d_qs = 0
        d_mode = c_mode
        if c_mode == MODE_POSITION:
            d_qref = c_q
    return d_mode, d_qref, d_int, d_tlim, d_qs


@kernel_jit
def torque_path(c_t, tmax, d_fault, sw_min, sw_max):
    """
    Return the torque command [N m] of a torque mode step: c_t saturated at tmax [N m].

    0 while a fault is latched, and toward a tripped limit switch.
    """
    t_sat = min(max(c_t, -tmax), tmax)
    if d_fault != FAULT_NONE:
        t_sat = 0.0
    if sw_min and t_sat < 0.0:
        t_sat = 0.0
    if sw_max and t_sat > 0.0:
        t_sat = 0.0
    return t_sat


# Drive update --------------------------------------------------------------------------------

@kernel_jit
def drive_update(q_fb, w_fb, w_ff, t_ff, w_lo, w_hi, sw_min, sw_max, d_mode, d_qref, d_int,
                 d_tout, d_fault, d_tlim, d_qs, d_wqs, d_ferr, d_wref, dc):
    """
    Run one update of the servo drive's position and velocity loops (drive.py).

    q_fb [rad], w_fb [rad/s]: feedback; w_ff [rad/s], t_ff [N m]: feed-forwards;
    w_lo, w_hi: bounds of the velocity reference [rad/s]; sw_min, sw_max:
    tripped limit switches; d_*: the drive state (load_drive); dc:
    drive_constants. Returns (d_mode, d_qref, d_int, d_tout, d_fault, d_tlim,
    d_qs, d_wqs, d_ferr, d_wref); d_tout [N m] is held until the next update.
    """
    kp_d, kv_d, ki_d, vmax, dw_qs, fel, tlt, tmax, td = dc
    if d_fault != FAULT_NONE:
        d_tout = 0.0
        d_int = 0.0
        d_tlim = 0.0
        d_wref = 0.0
    else:
        if d_mode == MODE_QUICKSTOP:
            if d_qs == 1:   # the ramp starts from the measured rate
                d_wqs = min(max(w_fb, -vmax), vmax)
                d_qs = 2
            if d_wqs > dw_qs:
                d_wqs -= dw_qs
            elif d_wqs < -dw_qs:
                d_wqs += dw_qs
            else:           # standstill: hold the position reached
                d_wqs = 0.0
                d_mode = MODE_POSITION
                d_qref = q_fb
            w_ref = d_wqs
        elif d_mode == MODE_POSITION:
            d_ferr = d_qref - q_fb
            w_ref = kp_d * d_ferr + w_ff
            if fel > 0.0 and abs(d_ferr) > fel:
                d_fault = FAULT_FOLLOWING_ERROR
        else:
            w_ref = w_ff
        w_ref = min(max(w_ref, w_lo), w_hi)
        t_drv, t_u, d_int = velocity_loop(w_ref, w_fb, d_int, kv_d, ki_d, t_ff, tmax, td)
        if abs(t_u) >= tmax:
            d_tlim += td
            if tlt > 0.0 and d_tlim > tlt:
                d_fault = FAULT_TORQUE_LIMIT
        else:
            d_tlim = 0.0
        if d_fault != FAULT_NONE:
            t_drv = 0.0
            d_int = 0.0
        # a tripped switch also cuts the torque toward it, as in torque
        # mode: the stop holds even when the feedback is wrong (frozen)
        if sw_min and t_drv < 0.0:
            t_drv = 0.0
        if sw_max and t_drv > 0.0:
            t_drv = 0.0
        d_wref = w_ref
        d_tout = t_drv
    return d_mode, d_qref, d_int, d_tout, d_fault, d_tlim, d_qs, d_wqs, d_ferr, d_wref


# Forces --------------------------------------------------------------------------------------

@kernel_jit
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


@inline_jit
def smooth_forces(qm, q, xa, xb, wm, dq, va, vb, te_new, fext, jam_side, jam_x, bc):
    """
    Return the smooth generalised forces of a substep and its contact forces.

    qm, q [rad], xa, xb [m], wm, dq [rad/s], va, vb [m/s]: positions and rates
    at the substep start; te_new: applied motor torque [N m]; fext: total
    external force on nut A [N]; jam_side: 1 or -1, the side of jam_x [m] the
    jam blocks (0: no jam); bc: body_constants. Returns (f_m, f_s, f_a, f_b,
    ct): forces on motor, screw [N m], nut A, half-nut B [N], and ct =
    (flo_a, fup_a, flo_b, fup_b, pen_lo_a, pen_up_a, pen_lo_b, pen_up_b,
    f_stop_lo, pen_stop_lo, f_stop_hi, pen_stop_hi, f_jam, pen_jam): in-plane
    lower/upper flank forces of each nut, end stop and jam forces [N], and
    their penetrations [m].
    """
    (rigid, two_nuts, rt, half_b, k, c, kc, cc, cs, cx, ma, mb, kes, ces, xmin, xmax, gs,
     f_pre, k_pre, backlash) = bc
    f_m = 0.0
    f_s = 0.0
    f_a = 0.0
    f_b = 0.0
    # motor and coupling
    if rigid:
        f_s += te_new
    else:
        f_m += te_new
        t_cspring = kc * (qm - q)
        t_cdamp = cc * (wm - dq)
        f_m -= t_cspring + t_cdamp
        f_s += t_cspring + t_cdamp
    # bearing and guide viscous, gravity, external force
    f_s -= cs * dq
    f_a -= cx * va
    f_a += fext - ma * gs
    if two_nuts:
        f_b -= mb * gs
    # end stops on nut A (unilateral, damper never pulls)
    f_stop_lo = 0.0
    f_stop_hi = 0.0
    pen_stop_lo = xmin - xa
    if pen_stop_lo > 0.0:
        f_stop_lo = max(0.0, kes * pen_stop_lo - ces * va)
        f_a += f_stop_lo
    pen_stop_hi = xa - xmax
    if pen_stop_hi > 0.0:
        f_stop_hi = max(0.0, kes * pen_stop_hi + ces * va)
        f_a -= f_stop_hi
    f_jam = 0.0
    pen_jam = 0.0
    if jam_side != 0.0:   # penetration past the jam, on its side; force against it
        pen_jam = jam_side * (xa - jam_x)
        if pen_jam > 0.0:
            f_jam = max(0.0, kes * pen_jam + ces * jam_side * va)
            f_a -= jam_side * f_jam
    # thread contact of nut A
    flo_a, fup_a, pen_lo_a, pen_up_a = _flank_forces(xa - rt * q, va - rt * dq, half_b, k, c)
    fn_a = flo_a - fup_a
    f_a += fn_a
    f_s -= rt * fn_a
    flo_b = 0.0
    fup_b = 0.0
    pen_lo_b = 0.0
    pen_up_b = 0.0
    if two_nuts:   # thread contact of half-nut B and the preload spring
        flo_b, fup_b, pen_lo_b, pen_up_b = _flank_forces(xb - rt * q, vb - rt * dq,
                                                         half_b, k, c)
        fn_b = flo_b - fup_b
        f_b += fn_b
        f_s -= rt * fn_b
        f_spring = f_pre + k_pre * (backlash - (xb - xa))
        f_b += f_spring
        f_a -= f_spring
    return f_m, f_s, f_a, f_b, (flo_a, fup_a, flo_b, fup_b, pen_lo_a, pen_up_a, pen_lo_b,
                                pen_up_b, f_stop_lo, pen_stop_lo, f_stop_hi, pen_stop_hi,
                                f_jam, pen_jam)


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


# Energy --------------------------------------------------------------------------------------

@kernel_jit
def energy_sums(sum_in, sum_ext, sum_damp, sum_fric, wm0, dq0, va0, vb0, wm, dq, va, vb,
                te_new, ct, jam_side, imp_a, imp_b, imp_c, imp_g, nact, a_alone, rc, sl, bc):
    """
    Add a substep's energy terms to the step's sums; return the four sums.

    The terms use start + end velocity (twice the mid-step velocity): sum_in
    [N m rad/s] motor power, sum_ext [m/s] nut A velocity (times the external
    force at the step's end), sum_damp [W] damper power, sum_fric [N m/s]
    friction impulses times velocity; the step scales them once.
    wm0 .. vb0, wm .. vb: velocities at the substep's start and end; te_new
    [N m]: applied motor torque; ct: contact forces (smooth_forces); jam_side:
    the jam's side (0: none); imp_*, nact, a_alone: friction_impulses; rc, sl:
    r_m cos(lambda) [m/rad], sin(lambda); bc: body_constants.
    """
    (rigid, two_nuts, rt, half_b, k, c, kc, cc, cs, cx, ma, mb, kes, ces, xmin, xmax, gs,
     f_pre, k_pre, backlash) = bc
    (flo_a, fup_a, flo_b, fup_b, pen_lo_a, pen_up_a, pen_lo_b, pen_up_b, f_stop_lo,
     pen_stop_lo, f_stop_hi, pen_stop_hi, f_jam, pen_jam) = ct
    wm_sum = wm0 + wm
    dq_sum = dq0 + dq
    va_sum = va0 + va
    vb_sum = vb0 + vb
    sum_in += te_new * (dq_sum if rigid else wm_sum)
    sum_ext += va_sum
    damp_pow = cs * dq0 * dq_sum + cx * va0 * va_sum
    if not rigid:
        damp_pow += cc * (wm0 - dq0) * (wm_sum - dq_sum)
    gap_sum_a = va_sum - rt * dq_sum   # start + end flank gap rate of nut A [m/s]
    if pen_lo_a > 0.0:
        damp_pow -= (flo_a - k * pen_lo_a) * gap_sum_a
    if pen_up_a > 0.0:
        damp_pow += (fup_a - k * pen_up_a) * gap_sum_a
    if pen_stop_lo > 0.0:
        damp_pow -= (f_stop_lo - kes * pen_stop_lo) * va_sum
    if pen_stop_hi > 0.0:
        damp_pow += (f_stop_hi - kes * pen_stop_hi) * va_sum
    if pen_jam > 0.0:
        damp_pow += jam_side * (f_jam - kes * pen_jam) * va_sum
    if two_nuts:
        gap_sum_b = vb_sum - rt * dq_sum
        if pen_lo_b > 0.0:
            damp_pow -= (flo_b - k * pen_lo_b) * gap_sum_b
        if pen_up_b > 0.0:
            damp_pow += (fup_b - k * pen_up_b) * gap_sum_b
    sum_damp += damp_pow
    if a_alone:
        sum_fric += imp_a * (rc * dq_sum + sl * va_sum)
    elif nact > 0:
        sum_fric += (imp_a * (rc * dq_sum + sl * va_sum)
                     + imp_b * (rc * dq_sum + sl * vb_sum)
                     + imp_c * dq_sum + imp_g * va_sum)
    return sum_in, sum_ext, sum_damp, sum_fric


# Outputs and write-back, once per step -------------------------------------------------------

@kernel_jit
def store_state(S, qm, wm, q, dq, xa, va, xb, vb, te, t, win, wext, efric, edamp, faprev,
                mode_a, mode_b, mode_c, mode_g, nsearch):
    """Write the mechanical state (the scalars of load_state) back into S."""
    S[S_QM] = qm
    S[S_WM] = wm
    S[S_Q] = q
    S[S_DQ] = dq
    S[S_XA] = xa
    S[S_VA] = va
    S[S_XB] = xb
    S[S_VB] = vb
    S[S_TE] = te
    S[S_T] = t
    S[S_WIN] = win
    S[S_WEXT] = wext
    S[S_EFRIC] = efric
    S[S_EDAMP] = edamp
    S[S_FAPREV] = faprev
    S[S_MODE0] = mode_a
    S[S_MODE0 + 1] = mode_b
    S[S_MODE0 + 2] = mode_c
    S[S_MODE0 + 3] = mode_g
    S[S_NSEARCH] = nsearch


@kernel_jit
def switch_states(xa, sw_min, sw_max, home, sc):
    """
    Return the limit and home switches (sw_min, sw_max, home) at nut position xa [m].

    Each with hysteresis from its last state; sc = (l_min, l_max, x_home, hyst)
    [m]: the switch positions and the hysteresis.
    """
    l_min, l_max, x_home, hyst = sc
    if sw_min:
        sw_min = not (xa > l_min + hyst)
    else:
        sw_min = xa <= l_min
    if sw_max:
        sw_max = not (xa < l_max - hyst)
    else:
        sw_max = xa >= l_max
    if home:
        home = not (xa < x_home - hyst)
    else:
        home = xa >= x_home
    return sw_min, sw_max, home


@kernel_jit
def store_drive(S, c_mode, c_q, c_w, c_t, d_mode, d_qref, d_int, d_tout, d_phase, d_fault,
                d_tlim, d_qs, d_wqs, d_ferr, d_wref, sw_min, sw_max, home, jam_side):
    """Write the held command, the drive state (load_drive), switches and jam into S."""
    S[S_CMODE] = c_mode
    S[S_CQ] = c_q
    S[S_CW] = c_w
    S[S_CT] = c_t
    S[S_DMODE] = d_mode
    S[S_DQREF] = d_qref
    S[S_DINT] = d_int
    S[S_DTOUT] = d_tout
    S[S_DPHASE] = d_phase
    S[S_DFAULT] = d_fault
    S[S_DTLIM] = d_tlim
    S[S_DQS] = d_qs
    S[S_DWQS] = d_wqs
    S[S_DFERR] = d_ferr
    S[S_DWREF] = d_wref
    S[S_SWMIN] = 1.0 if sw_min else 0.0
    S[S_SWMAX] = 1.0 if sw_max else 0.0
    S[S_HOME] = 1.0 if home else 0.0
    S[S_JAM] = jam_side


@kernel_jit
def thread_outputs(out, flo_a, fup_a, flo_b, fup_b, ff_a, ff_b, fa_thr, t_br, f_g, dq, va, vb,
                   te, mode_a, mode_b, rc, sl, rt, cl, two_nuts):
    """
    Write the outputs of the contacts and the motor of the last substep into out.

    flo_*, fup_*: flank forces [N]; ff_a, ff_b: thread friction forces [N];
    fa_thr: axial thread force [N]; t_br: bearing friction torque [N m]; f_g:
    guide friction force [N]; dq [rad/s], va, vb [m/s]: rates; te: applied
    motor torque [N m]; mode_a, mode_b: thread modes; rc, sl, rt, cl: r_m
    cos(lambda), sin(lambda), r_m tan(lambda), cos(lambda).
    """
    out[O_NLA] = flo_a / cl
    out[O_NUA] = fup_a / cl
    out[O_NLB] = flo_b / cl
    out[O_NUB] = fup_b / cl
    out[O_FFA] = ff_a
    out[O_FFB] = ff_b
    out[O_VSA] = rc * dq + sl * va
    out[O_VSB] = rc * dq + sl * vb if two_nuts else 0.0
    out[O_STICKA] = -1.0 if flo_a + fup_a <= 0.0 else (1.0 if mode_a == 0 else 0.0)
    out[O_STICKB] = -1.0 if flo_b + fup_b <= 0.0 else (1.0 if mode_b == 0 else 0.0)
    out[O_CONTA] = 1.0 if flo_a > 0.0 else (-1.0 if fup_a > 0.0 else 0.0)
    out[O_CONTB] = 1.0 if flo_b > 0.0 else (-1.0 if fup_b > 0.0 else 0.0)
    out[O_FAX] = fa_thr
    out[O_TTH] = -rt * (flo_a - fup_a + flo_b - fup_b) + rc * (ff_a + ff_b)
    out[O_TE] = te
    out[O_TBR] = t_br
    out[O_FG] = f_g


@kernel_jit
def drive_outputs(S, out, nsub, d_mode, d_fault, d_ferr, t_sat, d_wref, drive_on, jam_side):
    """
    Write the drive's outputs of the step into out (switches as stored in S).

    nsub: substeps of the step; d_*: the drive state; t_sat: the torque
    command [N m]; drive_on: the drive ran; jam_side: the jam's side (0: none).
    """
    out[O_NSUB] = nsub
    out[O_DMODE] = d_mode
    out[O_DFAULT] = d_fault
    out[O_SWMIN] = S[S_SWMIN]
    out[O_SWMAX] = S[S_SWMAX]
    out[O_HOME] = S[S_HOME]
    out[O_DFERR] = d_ferr if d_mode == MODE_POSITION else 0.0
    out[O_DTCMD] = t_sat
    out[O_DWREF] = d_wref if drive_on else 0.0
    out[O_JAM] = jam_side


@kernel_jit
def sensor_outputs(P, S, out, qm, wm, q, dq, xa, va, sampled, q_ref0, x_ref0, rt):
    """
    Write what the sensors report at the step's end into out (O_JQ .. O_JV).

    qm, q [rad], wm, dq [rad/s], xa [m], va [m/s]: true motor and screw angles
    and rates, nut A position and velocity; sampled: S_EQ .. S_VS hold the
    readings at the step's end (else the encoder and scale are read now);
    q_ref0 [rad], x_ref0 [m]: reference angle and nut position of the lead
    mapping; rt: r_m tan(lambda) [m/rad]. An ideal live encoder reports the
    true screw angle and rate; with no scale the position is the encoder's
    through the lead.
    """
    enc_live = P[P_EIDEAL] > 0.5 and P[P_EFRZ] <= 0.5
    if not sampled:
        eq_r, xs_r = readings(P, S, qm, xa)
    else:
        eq_r = S[S_EQ]
        xs_r = S[S_XS]
    eq = qm if enc_live else eq_r
    ew = wm if enc_live else S[S_EW]
    out[O_JQ] = q if enc_live else eq
    out[O_JW] = dq if enc_live else ew
    if P[P_SFIT] <= 0.5:   # no scale: the encoder through the lead
        out[O_JX] = x_ref0 + (eq - q_ref0) * rt
        out[O_JV] = ew * rt
    elif P[P_SIDEAL] > 0.5 and P[P_SFRZ] <= 0.5:
        out[O_JX] = xa
        out[O_JV] = va
    else:
        out[O_JX] = xs_r
        out[O_JV] = S[S_VS]
