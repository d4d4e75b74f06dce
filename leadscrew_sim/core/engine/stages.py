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
- friction impulses, every substep: :mod:`.impulses` (friction_impulses, with
  _impulses_pair and _impulses_general for two or more active elements);
- energy, every substep, and outputs and write-back, once per step:
  :mod:`.write_back` (energy_sums; store_state, switch_states, store_drive,
  thread_outputs, drive_outputs, sensor_outputs).

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
import math

from ._jit import DISPATCHERS, JIT_OPTIONS, kernel_jit, njit
from .drive import (
    FAULT_FOLLOWING_ERROR, FAULT_NONE, FAULT_TORQUE_LIMIT, MODE_POSITION, MODE_QUICKSTOP,
    MODE_TORQUE, velocity_loop,
)
from .friction import friction_constants
from .layout import (
    P_AB, P_B, P_C, P_CC, P_CES, P_CL, P_CS, P_CX, P_DFEL, P_DKP, P_DKV, P_DQSD, P_DTI, P_DTLT,
    P_DVMAX, P_FP, P_FX0, P_GS, P_JM, P_JS, P_K, P_KC, P_KES, P_KP, P_MA, P_MB, P_MUC, P_RC,
    P_RCOL, P_RIGID, P_RT, P_SL, P_TMAX, P_TS0, P_XMAX, P_XMIN, S_CQ, S_CW, S_DFAULT, S_DFERR,
    S_DINT, S_DMODE, S_DPHASE, S_DQ, S_DQREF, S_DQS, S_DTLIM, S_DTOUT, S_DWQS, S_DWREF,
    S_EDAMP, S_EFRIC, S_FAPREV, S_MODE0, S_NSEARCH, S_Q, S_QM, S_T, S_TE, S_VA, S_VB, S_WEXT,
    S_WIN, S_WM, S_XA, S_XB,
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
def take_command(c_mode, c_q, d_mode, d_qref, d_int, d_tlim, d_qs, d_wqs, q_now, jump, slew_v,
                 slew_a, dt):
    """
    Let the held command take effect: a quick stop once, any other mode at once.

    c_mode, c_q: held mode and target [rad]; d_*: the drive state (load_drive);
    q_now: the motor angle [rad]; jump: max_command_jump as a motor angle
    [rad] (0: off); slew_v [rad/s], slew_a [rad/s^2]: the rate and
    acceleration of the reference's approach; dt: the step [s].

    A position target within ``jump`` of the reference (of q_now when the
    drive enters position mode) becomes the reference at once. A farther one
    is approached by a trapezoidal reference: its rate d_wqs [rad/s] (the
    quick stop's slot, free in position mode; the kernel adds it to the
    velocity feed-forward) grows by slew_a dt per step up to slew_v and slows
    to arrive, so the drive moves there at its limits instead of stepping.
    Returns (d_mode, d_qref, d_int, d_tlim, d_qs, d_wqs).
    """
    if c_mode == MODE_QUICKSTOP:
        if d_qs == 0:
            if d_mode == MODE_TORQUE:
                d_int = 0.0
                d_tlim = 0.0
            d_mode = MODE_QUICKSTOP
            d_qs = 1
        return d_mode, d_qref, d_int, d_tlim, d_qs, d_wqs
    if d_mode == MODE_TORQUE and c_mode != MODE_TORQUE:   # the drive starts afresh
        d_int = 0.0
        d_tlim = 0.0
    d_qs = 0
    was = d_mode
    d_mode = c_mode
    if c_mode != MODE_POSITION or jump <= 0.0:
        d_wqs = 0.0
        if c_mode == MODE_POSITION:
            d_qref = c_q
        return d_mode, d_qref, d_int, d_tlim, d_qs, d_wqs
    if was != MODE_POSITION:
        d_qref = q_now
        d_wqs = 0.0
    e = c_q - d_qref
    if abs(e) <= jump and abs(d_wqs) * dt <= jump:
        d_qref = c_q
        d_wqs = 0.0
    else:
        cap = min(slew_v, math.sqrt(2.0 * slew_a * abs(e)))
        want = cap if e > 0.0 else -cap
        dv = slew_a * dt
        d_wqs = min(max(want, d_wqs - dv), d_wqs + dv)
        d_qref += d_wqs * dt
        if (c_q - d_qref) * e <= 0.0:    # arrived (or passed): the target itself
            d_qref = c_q
            d_wqs = 0.0
    return d_mode, d_qref, d_int, d_tlim, d_qs, d_wqs


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
def _flank_forces(gap, gap_rate, hlo, hup, k, c):
    """
    Return (lower, upper) in-plane flank forces [N] and penetrations [m] of a nut body.

    gap = x - r_m tan(lambda) q [m], gap_rate its rate [m/s], hlo, hup the
    half gaps of the lower and upper flank [m] (half the backlash plus the
    flank's wear, ageing.flank_gaps): compliant flanks (k [N/m], c [N s/m])
    that never pull.
    """
    el = -gap - hlo
    eu = gap - hup
    pl = 0.0
    pu = 0.0
    if el > 0.0:
        pl = max(0.0, k * el - c * gap_rate)
    if eu > 0.0:
        pu = max(0.0, k * eu + c * gap_rate)
    return pl, pu, el, eu


@inline_jit
def smooth_forces(qm, q, xa, xb, wm, dq, va, vb, te_new, fext, jam_side, jam_x, bc, wr, k_tie):
    """
    Return the smooth generalised forces of a substep and its contact forces.

    qm, q [rad], xa, xb [m], wm, dq [rad/s], va, vb [m/s]: positions and rates
    at the substep start; te_new: applied motor torque [N m]; fext: total
    external force on nut A [N]; jam_side: 1 or -1, the side of jam_x [m] the
    jam blocks (0: no jam); bc: body_constants; wr: the flanks' half gaps
    (ageing.flank_gaps); k_tie [N/m]: stiffness of the preload spring's end of
    travel, a tie that holds the halves of a split nut at the spring's free
    length (0: none, the spring is linear throughout). Returns (f_m, f_s, f_a, f_b,
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
    hlo_a, hup_a, hlo_b, hup_b = wr
    flo_a, fup_a, pen_lo_a, pen_up_a = _flank_forces(xa - rt * q, va - rt * dq, hlo_a, hup_a,
                                                     k, c)
    fn_a = flo_a - fup_a
    f_a += fn_a
    f_s -= rt * fn_a
    flo_b = 0.0
    fup_b = 0.0
    pen_lo_b = 0.0
    pen_up_b = 0.0
    if two_nuts:   # thread contact of half-nut B and the preload spring
        flo_b, fup_b, pen_lo_b, pen_up_b = _flank_forces(xb - rt * q, vb - rt * dq,
                                                         hlo_b, hup_b, k, c)
        fn_b = flo_b - fup_b
        f_b += fn_b
        f_s -= rt * fn_b
        f_spring = f_pre + k_pre * (backlash - (xb - xa))
        if k_tie > 0.0 and f_spring < 0.0:   # past the free length: the tie pulls
            f_spring *= k_tie / k_pre
        f_b += f_spring
        f_a -= f_spring
    return f_m, f_s, f_a, f_b, (flo_a, fup_a, flo_b, fup_b, pen_lo_a, pen_up_a, pen_lo_b,
                                pen_up_b, f_stop_lo, pen_stop_lo, f_stop_hi, pen_stop_hi,
                                f_jam, pen_jam)
