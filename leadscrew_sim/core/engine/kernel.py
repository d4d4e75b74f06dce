"""
Fixed-step integration kernel of the lead screw model (ROS-free, numba-compiled).

Generalised coordinates, all in the "q sense" of physics.md section 3
(q = hand sign times theta, so x = r_m tan(lambda) q for every hand):
    u = [motor angle rate, screw angle rate, nut A velocity, half-nut B velocity].

One substep is semi-implicit (symplectic) Euler. Smooth forces (springs,
dampers, gravity, motor) are explicit; every Coulomb-type element (thread
friction of each nut body, screw bearing plus thrust collar, nut guide) is an
implicit velocity-level impulse bounded by its friction limit, found by solving
the small box-constrained LCP exactly. A stuck element keeps its sliding
velocity at zero to round-off, so a self-locking screw does not creep
(no tanh or ramp regularisation).

The servo drive (drive.py, physics.md section 10) runs inside the substep
loop: in velocity, position and quick stop mode it updates the held motor
torque command every m substeps; in torque mode it does not run and the
step takes the torque path of the kernel without a drive.

This module holds the integrator (_steps, with the flank contact law
_flank_forces) and its entry points step, step_held and run_series, plus
workspace(). The array layouts are in layout, the friction law in friction,
the drive's loop law in drive, the LCP solvers in lcp; the compile options,
shared by all, in _jit.
"""
import math

import numpy as np

from ._jit import kernel_jit, refresh_cache
from .drive import (
    FAULT_FOLLOWING_ERROR, FAULT_INJECTED, FAULT_NONE, FAULT_TORQUE_LIMIT, MODE_POSITION,
    MODE_QUICKSTOP, MODE_TORQUE, update_period, velocity_loop,
)
from .friction import _thread_limit, _thread_limits, friction_constants
from .lcp import _box1, _box2, _friction_lcp, _solve2, _solve_free
from .sensors import readings, sample
from .layout import (
    IWK_EID, IWK_IDX, IWK_MODE, IWK_TRIAL,
    MAXE, NO, N_CMD,
    O_CONTA, O_CONTB, O_DFAULT, O_DFERR, O_DMODE, O_DTCMD, O_DWREF, O_FAX, O_FFA, O_FFB, O_FG,
    O_HOME, O_JAM, O_JQ, O_JV, O_JW, O_JX, O_NLA, O_NLB, O_NSUB, O_NUA, O_NUB, O_STICKA, O_STICKB,
    O_SWMAX, O_SWMIN, O_TBR, O_TE, O_TTH, O_VSA, O_VSB,
    P_AB, P_B, P_C, P_CC, P_CES, P_CL, P_CS, P_CX, P_DFEL, P_DKP, P_DKV, P_DQ0, P_DQSD,
    P_DRATE, P_DSCALE, P_DTI, P_DTLT, P_DVMAX, P_DX0, P_EFRZ, P_EIDEAL, P_FEXT, P_FINJ, P_FP,
    P_FX0, P_GS, P_HOME, P_HYST, P_JAM, P_JAMX, P_JM, P_JS, P_K, P_KC, P_KES, P_KP, P_LMAX,
    P_LMIN, P_MA, P_MB, P_MUC, P_RC, P_RCOL, P_RIGID, P_RT, P_SFIT, P_SFRZ, P_SIDEAL, P_SL,
    P_TAU, P_TMAX, P_TS0, P_TSCALE, P_VFT, P_XMAX, P_XMIN,
    REC_ROW, REC_STATE,
    S_CMODE, S_CQ, S_CT, S_CW, S_DFAULT, S_DFERR, S_DINT, S_DMODE, S_DPHASE, S_DQ, S_DQREF,
    S_DQS, S_DTLIM, S_DTOUT, S_DWQS, S_DWREF, S_EDAMP, S_EFRIC, S_EQ, S_EW, S_FAPREV, S_HOME,
    S_JAM, S_MODE0, S_NREP, S_NSAMP, S_NSEARCH, S_Q, S_QM, S_SWMAX, S_SWMIN, S_T, S_TE, S_VA,
    S_VB, S_VS,
    S_WEXT, S_WIN, S_WM, S_XA, S_XB, S_XS,
    WK_A, WK_CMD, WK_FLOAT, WK_INT, WK_IO, WK_LCP, WK_LIM, WK_NIO, WK_P, WK_R, WK_REC, WK_V0,
    WK_W,
)


def workspace():
    """Return the (float, int) scratch arrays that step() and run_series() need."""
    return np.zeros(WK_FLOAT), np.zeros(WK_INT, dtype=np.int64)


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


@kernel_jit
def _steps(P, S, out, torques, forces, cmds, dt, nsub, wk, iwk, rec):
    """
    Advance S by one step of dt (nsub equal substeps) per entry of torques/forces.

    torques: commanded motor torques [N m] in the q sense; forces: external
    axial forces on nut A [N] added to the parameter one. cmds: drive
    command rows (mode, q_ref [rad], w_cmd [rad/s], t_cmd [N m], q sense),
    either none (shape (0, N_CMD): every step in torque mode with torques[i])
    or one per step (row i becomes the held command of step i; torques is
    then unused, the steps are as many as the shorter of the two). After step
    i, out holds its outputs and rec[i] = S[:REC_STATE] + out. Returns the
    number of steps done; fewer if a state became non-finite, with S and out
    as they were before the failing step.

    The drive (drive.py) runs in the substep loop while its mode is not torque:
    every d_m substeps (phase counter d_phase, continuous across steps) it reads
    its feedback at the one marked place, runs the position and velocity loops
    and holds the new torque command t_sat until its next update. A torque mode
    step takes the torque path: t_sat = clip(command), clamped to 0 by a latched
    fault or toward a tripped limit switch, the same for every substep. In
    every mode the sensors (sensors.sample) are sampled at the end of each
    drive period, when d_phase wraps to 0: the drive's feedback is that sample.
    The motor delivers t_scale times the torque command (a weakened motor), an
    injected fault latches while its flag is set, and a jam is a one-sided end
    stop at jam_x on the side nut A was when it engaged.

    Parameters are unpacked once per call and the state lives in local scalars
    within a step. One or two active friction elements are solved by the
    scalar _box1/_box2, three or four by the general box LCP on the workspace
    arrays; all give the same impulses (test/core/test_kernel_lcp.py).

    Friction elements, in this order: a thread of nut A, b thread of half-nut B,
    c screw bearing plus thrust collar, g nut guide (ids 0, 1, 2, 3). Bodies:
    m motor, s screw, a nut A, b half-nut B. Angles, rates and torques are in
    the q sense; "impulse" is per substep [N s] (bearing: [N m s]).

    Locals (name: meaning [unit]):
      h: substep dt / nsub [s];  rigid: motor and screw are one body;
      two_nuts: the anti-backlash half-nut B is simulated
      rt, rc, sl, cl: r_m tan(lambda) [m/rad], r_m cos(lambda) [m/rad],
        sin(lambda), cos(lambda) [-]
      half_b, backlash: half the backlash, the backlash [m]
      k, c: flank contact stiffness [N/m] and damping [N s/m]
      kc, cc: coupling stiffness [N m/rad] and damping [N m s/rad]
      cs, cx: bearing [N m s/rad] and guide [N s/m] viscous damping
      ma, mb: masses of nut A (with payload) and half-nut B [kg]
      kes, ces, xmin, xmax: end stops of nut A [N/m], [N s/m], [m], [m]
      fc: the thread friction law's constants (friction.friction_constants)
      hcl, hcl_lo: h / cos(lambda) [s], and less 1e-14 relative for the stick bound
      f_pre, k_pre: anti-backlash preload [N] and spring stiffness [N/m]
      ts0: bearing Coulomb torque [N m];  mu_r_col: collar mu times radius [m]
      lim_g: guide impulse limit [N s];  gs: g sin(inclination) [m/s^2]
      mi_m, mi_s, mi_a, mi_b: inverse inertia [1/(kg m^2)] or mass [1/kg] of the
        bodies (mi_s includes the motor if rigid)
      hmi_m, hmi_s, hmi_a, hmi_b: h times these: velocity change per unit force
      w_aa, w_ab, w_ac, w_ag, w_bb: Delassus entries J_x M^-1 J_y^T of the
        elements x, y (w_bc = w_ac, w_cc = mi_s, w_gg = mi_a, the rest 0)
      w_table: the full 4 x 4 Delassus matrix, row-major in element order
      nrecip_w_aa: -1 / (regularised w_aa), the stick impulse per unit velocity
      alpha: motor torque lag factor per substep [-]
      t_sat: saturated torque command [N m];  fext: total external force [N]
      tmax: torque saturation [N m];  ncmd: number of command rows (0: torque mode)
      drive (q sense): d_m: substeps per drive update;  td: drive period d_m h [s];
        kp_d, kv_d, ki_d: K_p [1/s], K_v [N m s/rad], K_v / T_i [N m/rad] (0: no
        integral);  vmax: velocity limit
        [rad/s];  dw_qs: quick stop rate decrement per update [rad/s];  fel: following
        error limit [rad];  tlt: torque limit time [s];  scale_fb: position feedback
        from the linear scale;  q_ref0, x_ref0, irt: its reference angle [rad] and nut
        position [m], 1 / rt [rad/m];  l_min, l_max, x_home, hyst: switch positions and
        hysteresis [m]
      sensors: eq0, ew0, xs0, vs0, ns0, nr0: the sensor slots at the step's start;
        beta: velocity filter gain per sample;  ideal_fb: both sensors ideal and
        live (no sampling: the drive reads the state, S_EQ .. S_VS get the truth);
        t_scale: motor torque scale;  jam_on, jam_x, jam_side: the jam, its position
        [m] and side (1 blocks +x, -1 blocks -x);  f_jam, pen_jam: its force [N]
        and penetration [m];  count_phase: the phase is counted substep by substep
        (the drive runs or a sensor is sampled);  enc_live: the encoder is ideal
        and not frozen;  eq_r, xs_r: encoder [rad] and scale [m] readings at the
        step's end;  eq, ew: encoder angle [rad] and rate [rad/s] reported
      c_mode, c_q, c_w, c_t: the held command (mode, q_ref [rad], w_cmd [rad/s],
        t_cmd [N m]);  d_mode: active mode;  d_qref: active target [rad];  d_int:
        integral I [rad];  d_tout: held drive torque command [N m];  d_phase: substeps
        since the last update;  d_fault: latched fault code;  d_tlim: time at the torque
        limit [s];  d_qs: quick stop state: 0 none, 1 requested, 2 ramping or
        holding the stop position;  d_wqs: quick stop ramp [rad/s];  d_ferr: following
        error [rad];  d_wref: velocity reference [rad/s];  sw_min, sw_max, home: switch
        states
      drive_on: the drive runs this step (mode not torque);  q_fb, w_fb: the drive's
        feedback [rad], [rad/s];  w_ref, w_ff, t_ff: velocity reference and
        feed-forwards;  w_lo, w_hi: bounds of w_ref [rad/s];  t_drv,
        t_u: loop output clipped and unclipped [N m]
      qm, q, xa, xb: motor angle, screw angle [rad]; nut A, B positions [m]
      wm, dq, va, vb: motor rate, screw rate [rad/s]; nut A, B velocities [m/s]
      wm0, dq0, va0, vb0: the same at the start of the substep
      wm_sum, dq_sum, va_sum, vb_sum: start + end velocity of the substep (twice
        the mid-step velocity), for the energy sums
      qm_new, q_new, xa_new, xb_new, te_new: positions and motor torque after
        the substep
      te: applied motor torque [N m];  t: time [s]
      win, wext, efric, edamp: the energies of S_WIN .. S_EDAMP [J]
      faprev: axial thread force of the last substep [N] (collar limit)
      mode_a, mode_b, mode_c, mode_g: stick/slip mode of each element (-1, 0, 1),
        the warm start of the next substep
      nsearch: count of warm-start misses [-]
      f_m, f_s, f_a, f_b: smooth generalised forces on the bodies [N m], [N]
      t_cspring, t_cdamp: coupling spring and damper torques [N m]
      pen_stop_lo, pen_stop_hi: end stop penetrations [m];  f_stop_lo,
        f_stop_hi: their forces [N]
      flo_a, fup_a, flo_b, fup_b: in-plane lower/upper flank forces of nut A/B [N]
      pen_lo_a, pen_up_a, pen_lo_b, pen_up_b: their flank penetrations [m]
      fn_a, fn_b: net flank force on nut A/B [N];  f_spring: preload spring [N]
      load_a, load_b: flank load of the thread, flo + fup [N]
      vs_a, vs_b: thread sliding velocities at the substep start [m/s]
      lim_a, lim_b, lim_c: impulse limits (0: inactive; -1: stuck thread whose
        limit is not computed yet);  lo_a, lo_b: exp-free lower bounds of them
      nact: number of active friction elements;  a_alone: thread A is the only one
      imp_a, imp_b, imp_c, imp_g: friction impulses of the substep
      vfree_a: thread A sliding velocity before friction [m/s]
      searched: the warm-start mode was not the solution
      lim_of, lo_of, vfree_of, mode_of: limits, bounds, free velocities, modes
        of the elements, indexed by element id
      e1, e2: ids of the one or two active elements (e2 = -1 if one)
      lim1, vfree1, w1, imp1, mode1 (and ...2), w12: the scalar LCP of e1 (e2)
      W, v0, lim, p, A, r, mode, eid, idx, trial: workspace views of the general
        LCP (see lcp._solve_free; eid: element id of each active slot)
      sum_in, sum_ext, sum_damp, sum_fric: per-step sums of the energy terms
      damp_pow: the substep's damper term;  gap_sum_a, gap_sum_b: start + end
        flank gap rate of nut A/B [m/s]
      ff_a, ff_b: thread friction forces [N];  t_br: bearing friction torque
        [N m];  f_g: guide friction force [N];  fa_thr: axial thread force [N]
    """
    h = dt / nsub
    rigid = P[P_RIGID] > 0.5
    two_nuts = P[P_AB] > 0.5
    rt = P[P_RT]
    rc = P[P_RC]
    sl = P[P_SL]
    cl = P[P_CL]
    half_b = 0.5 * P[P_B]
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
    fc = friction_constants(P)
    # Limits are mu' N h / cos(lambda); the stick bound uses h / cos(lambda) less 1e-14,
    # so its limit stays below the exact one whatever the rounding of either.
    hcl = h / cl
    hcl_lo = hcl * (1.0 - 1e-14)
    f_pre = P[P_FP]
    k_pre = P[P_KP]
    backlash = P[P_B]
    ts0 = P[P_TS0]
    mu_r_col = P[P_MUC] * P[P_RCOL]
    lim_g = h * P[P_FX0]
    # inverse masses; element Jacobian rows (q sense): thread A [0, rc, sl, 0],
    # thread B [0, rc, 0, sl], bearing/collar [0, 1, 0, 0], guide [0, 0, 1, 0]
    mi_m = 1.0 / P[P_JM]
    mi_s = 1.0 / (P[P_JS] + (P[P_JM] if rigid else 0.0))
    mi_a = 1.0 / ma
    mi_b = 1.0 / mb
    # Delassus matrix entries J_x M^-1 J_y^T of the elements x, y (w_bg = w_cg = 0)
    w_aa = rc * rc * mi_s + sl * sl * mi_a
    w_ab = rc * rc * mi_s
    w_ac = rc * mi_s
    w_ag = sl * mi_a
    w_bb = rc * rc * mi_s + sl * sl * mi_b
    hmi_m = h * mi_m   # velocity change per unit force in a substep [s/(kg m^2), s/kg]
    hmi_s = h * mi_s
    hmi_a = h * mi_a
    hmi_b = h * mi_b
    nrecip_w_aa = -1.0 / (w_aa + (1e-12 * w_aa + 1e-300))
    # the full symmetric 4 x 4 matrix, row-major, for the general LCP
    w_table = (w_aa, w_ab, w_ac, w_ag,
               w_ab, w_bb, w_ac, 0.0,
               w_ac, w_ac, mi_s, 0.0,
               w_ag, 0.0, 0.0, mi_a)
    alpha = 1.0 if P[P_TAU] <= 0.0 else 1.0 - math.exp(-h / P[P_TAU])
    gs = P[P_GS]
    tmax = P[P_TMAX]
    # servo drive
    ncmd = cmds.shape[0]
    d_m = update_period(nsub, dt, P[P_DRATE])
    td = d_m * h
    kp_d = P[P_DKP]
    kv_d = P[P_DKV]
    ki_d = P[P_DKV] / P[P_DTI] if P[P_DTI] > 0.0 else 0.0
    vmax = P[P_DVMAX]
    dw_qs = P[P_DQSD] * td
    fel = P[P_DFEL]
    tlt = P[P_DTLT]
    scale_fb = P[P_DSCALE] > 0.5
    q_ref0 = P[P_DQ0]
    x_ref0 = P[P_DX0]
    irt = 1.0 / rt
    l_min = P[P_LMIN]
    l_max = P[P_LMAX]
    x_home = P[P_HOME]
    hyst = P[P_HYST]
    beta = 1.0 if P[P_VFT] <= 0.0 else 1.0 - math.exp(-td / P[P_VFT])
    t_scale = P[P_TSCALE]
    jam_on = P[P_JAM] > 0.5
    jam_x = P[P_JAMX]
    # ideal live sensors read the truth: no sampling in the substeps, the feedback is the state
    ideal_fb = (P[P_EIDEAL] > 0.5 and P[P_EFRZ] <= 0.5 and P[P_SIDEAL] > 0.5
                and P[P_SFRZ] <= 0.5)
    n_steps = torques.shape[0] if ncmd == 0 else min(torques.shape[0], ncmd)
    for i in range(n_steps):
        fext = P[P_FEXT] + forces[i]
        # the held command: a row of cmds, or torque mode with torques[i]
        if ncmd > 0:
            c_mode = int(cmds[i, 0])
            c_q = cmds[i, 1]
            c_w = cmds[i, 2]
            c_t = cmds[i, 3]
        else:
            c_mode = MODE_TORQUE
            c_q = S[S_CQ]
            c_w = S[S_CW]
            c_t = torques[i]
        d_mode = int(S[S_DMODE])
        d_qref = S[S_DQREF]
        d_int = S[S_DINT]
        d_tout = S[S_DTOUT]
        d_phase = int(S[S_DPHASE])
        d_fault = int(S[S_DFAULT])
        d_tlim = S[S_DTLIM]
        d_qs = int(S[S_DQS])
        d_wqs = S[S_DWQS]
        d_ferr = S[S_DFERR]
        d_wref = S[S_DWREF]
        # the sensor slots the substeps write, restored if the step fails
        eq0, ew0, xs0, vs0, ns0 = S[S_EQ], S[S_EW], S[S_XS], S[S_VS], S[S_NSAMP]
        nr0 = S[S_NREP]
        if P[P_FINJ] > 0.5 and d_fault == FAULT_NONE:   # an injected fault latches
            d_fault = FAULT_INJECTED
        jam_side = 0.0
        if jam_on:   # the jam blocks the side of jam_x the nut was on when it engaged
            jam_side = S[S_JAM]
            if jam_side == 0.0:
                jam_side = 1.0 if S[S_XA] <= jam_x else -1.0
        # the command takes effect: a quick stop once, any other mode at once
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
        # limit and home switches, as the end of the last step left them
        sw_min = S[S_SWMIN] > 0.5
        sw_max = S[S_SWMAX] > 0.5
        drive_on = d_mode != MODE_TORQUE
        count_phase = drive_on or not ideal_fb   # else the phase advances once, after the step
        # bounds of the velocity reference: the velocity limit, and 0 toward a tripped
        # switch (rt > 0: w_ref < 0 moves the nut toward -x); one clip applies both
        w_lo = 0.0 if sw_min else -vmax
        w_hi = 0.0 if sw_max else vmax
        w_ff = 0.0 if d_qs != 0 else c_w     # a quick stop and its hold: no feed-forwards
        t_ff = 0.0 if d_qs != 0 else c_t
        if drive_on:
            t_sat = d_tout
        else:   # torque mode: the command, saturated; off while faulted or toward a switch
            t_sat = min(max(c_t, -P[P_TMAX]), P[P_TMAX])
            if d_fault != FAULT_NONE:
                t_sat = 0.0
            if sw_min and t_sat < 0.0:
                t_sat = 0.0
            if sw_max and t_sat > 0.0:
                t_sat = 0.0
            d_tout = t_sat
        # state in locals
        qm = S[S_QM]
        q = S[S_Q]
        xa = S[S_XA]
        xb = S[S_XB]
        wm = S[S_WM]
        dq = S[S_DQ]
        va = S[S_VA]
        vb = S[S_VB]
        te = S[S_TE]
        t = S[S_T]
        win = S[S_WIN]
        wext = S[S_WEXT]
        efric = S[S_EFRIC]
        edamp = S[S_EDAMP]
        faprev = S[S_FAPREV]
        mode_a = int(S[S_MODE0])
        mode_b = int(S[S_MODE0 + 1])
        mode_c = int(S[S_MODE0 + 2])
        mode_g = int(S[S_MODE0 + 3])
        nsearch = S[S_NSEARCH]
        flo_a = fup_a = flo_b = fup_b = 0.0
        imp_a = imp_b = imp_c = imp_g = 0.0
        sum_in = sum_ext = sum_damp = sum_fric = 0.0   # energy sums of the step (see below)
        sub = 0
        while sub < nsub:
            # one drive period at a time (the whole step when no phase is counted): the
            # drive's update and the sensors' sample stay out of the inner substep loop
            seg = nsub - sub
            if count_phase and d_m - d_phase < seg:
                seg = max(1, d_m - d_phase)
            if drive_on and d_phase == 0:
                # drive feedback: the sensors' sample at the end of the last period
                if ideal_fb:
                    q_fb = q_ref0 + (xa - x_ref0) * irt if scale_fb else qm
                    w_fb = wm
                else:
                    q_fb = q_ref0 + (S[S_XS] - x_ref0) * irt if scale_fb else S[S_EQ]
                    w_fb = S[S_EW]
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
                    t_drv, t_u, d_int = velocity_loop(w_ref, w_fb, d_int, kv_d, ki_d, t_ff,
                                                      tmax, td)
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
                t_sat = d_tout
            for _ in range(seg):
                te_new = te + alpha * (t_scale * t_sat - te)
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
                flo_a, fup_a, pen_lo_a, pen_up_a = _flank_forces(xa - rt * q, va - rt * dq,
                                                                 half_b, k, c)
                fn_a = flo_a - fup_a
                f_a += fn_a
                f_s -= rt * fn_a
                flo_b = 0.0
                fup_b = 0.0
                pen_lo_b = 0.0
                pen_up_b = 0.0
                if two_nuts:
                    flo_b, fup_b, pen_lo_b, pen_up_b = _flank_forces(xb - rt * q, vb - rt * dq,
                                                                     half_b, k, c)
                    fn_b = flo_b - fup_b
                    f_b += fn_b
                    f_s -= rt * fn_b
                    f_spring = f_pre + k_pre * (backlash - (xb - xa))
                    f_b += f_spring
                    f_a -= f_spring
                # unconstrained velocity
                wm0 = wm
                dq0 = dq
                va0 = va
                vb0 = vb
                if not rigid:
                    wm = wm + f_m * hmi_m
                dq = dq + f_s * hmi_s
                va = va + f_a * hmi_a
                if two_nuts:
                    vb = vb + f_b * hmi_b
                # friction limits of the elements (0: inactive; -1: stuck thread, bound only)
                load_a = flo_a + fup_a
                load_b = flo_b + fup_b
                vs_a = rc * dq0 + sl * va0
                vs_b = rc * dq0 + sl * vb0
                lim_a, lo_a = _thread_limits(load_a, mode_a, vs_a, fc, hcl, hcl_lo)
                lim_b, lo_b = _thread_limits(load_b, mode_b, vs_b, fc, hcl, hcl_lo)
                lim_c = h * (ts0 + mu_r_col * abs(faprev))
                nact = int(lim_a != 0.0) + int(lim_b != 0.0) + int(lim_c > 0.0) + int(lim_g > 0.0)
                # impulses of thread A, thread B, bearing, guide
                imp_a = imp_b = imp_c = imp_g = 0.0
                a_alone = nact == 1 and lim_a != 0.0
                if a_alone:   # thread A alone, the common case, without the tables below
                    vfree_a = rc * dq + sl * va
                    searched = False
                    if lim_a < 0.0:   # stuck warm start: the stick impulse of _box1, on the bound
                        imp_a = vfree_a * nrecip_w_aa
                        if abs(imp_a) > lo_a * (1.0 + 1e-9):
                            lim_a = _thread_limit(load_a, vs_a, fc, hcl)
                            imp_a, mode_a, searched = _box1(w_aa, vfree_a, lim_a, 0)
                    else:
                        imp_a, mode_a, searched = _box1(w_aa, vfree_a, lim_a, mode_a)
                    if searched:
                        nsearch += 1.0
                elif 0 < nact <= 2:
                    # elements e1 < e2 (e2 = -1 if one): 0 thread A, 1 thread B, 2 bearing, 3 guide
                    lim_of = (lim_a, lim_b, lim_c, lim_g)
                    lo_of = (lo_a, lo_b, lim_c, lim_g)
                    vfree_of = (rc * dq + sl * va, rc * dq + sl * vb, dq, va)
                    mode_of = (mode_a, mode_b, mode_c, mode_g)
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
                            imp1, imp2, ok = _solve2(w1, w12, w2, vfree1, vfree2,
                                                     lo_of[e1], lo_of[e2], 0, 0)
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
                    if searched:
                        nsearch += 1.0
                    imp_a = imp1 if e1 == 0 else 0.0
                    imp_b = imp1 if e1 == 1 else (imp2 if e2 == 1 else 0.0)
                    imp_c = imp1 if e1 == 2 else (imp2 if e2 == 2 else 0.0)
                    imp_g = imp1 if e1 == 3 else (imp2 if e2 == 3 else 0.0)
                    mode_a = mode1 if e1 == 0 else mode_a
                    mode_b = mode1 if e1 == 1 else (mode2 if e2 == 1 else mode_b)
                    mode_c = mode1 if e1 == 2 else (mode2 if e2 == 2 else mode_c)
                    mode_g = mode1 if e1 == 3 else (mode2 if e2 == 3 else mode_g)
                elif nact > 2:   # the general box LCP on the workspace arrays
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
                    if not _solve_free(W, v0, lim, mode, nact, p, A, r, idx):
                        nsearch += 1.0
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
                if a_alone:
                    dq += imp_a * w_ac
                    va += imp_a * w_ag
                elif nact > 0:   # element by element, in element order (adding 0 changes nothing)
                    dq += rc * imp_a * mi_s
                    va += sl * imp_a * mi_a
                    dq += rc * imp_b * mi_s
                    vb += sl * imp_b * mi_b
                    dq += imp_c * mi_s
                    va += imp_g * mi_a
                if rigid:
                    wm = dq
                if not two_nuts:
                    vb = va
                # positions (symplectic Euler)
                qm_new = qm + h * wm
                q_new = q + h * dq
                xa_new = xa + h * va
                xb_new = xb + h * vb
                # energy bookkeeping with the mid-step velocities (start + end) / 2, summed over
                # the step and scaled once at its end
                wm_sum = wm0 + wm
                dq_sum = dq0 + dq
                va_sum = va0 + va
                vb_sum = vb0 + vb
                sum_in += te_new * (dq_sum if rigid else wm_sum)
                sum_ext += va_sum
                damp_pow = cs * dq0 * dq_sum + cx * va0 * va_sum
                if not rigid:
                    damp_pow += cc * (wm0 - dq0) * (wm_sum - dq_sum)
                gap_sum_a = va_sum - rt * dq_sum
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
                # the next collar limit needs this substep's axial thread force
                if mu_r_col > 0.0:
                    faprev = (flo_a - fup_a) + (imp_a / h) * sl
                    if two_nuts:
                        faprev += (flo_b - fup_b) + (imp_b / h) * sl
                qm = qm_new
                q = q_new
                xa = xa_new
                xb = xb_new
                te = te_new
                t += h
            sub += seg
            if count_phase:
                d_phase += seg
                if d_phase >= d_m:   # the end of a drive period: sample the sensors
                    d_phase = 0
                    if not ideal_fb:
                        sample(P, S, qm, wm, xa, va, td, beta, False)
        win += 0.5 * h * sum_in
        wext += 0.5 * h * fext * sum_ext
        edamp += 0.5 * h * sum_damp
        efric -= 0.5 * sum_fric
        # friction forces [N, N m] and the axial thread force of the last substep
        ff_a = imp_a / h
        ff_b = imp_b / h
        t_br = imp_c / h
        f_g = imp_g / h
        fa_thr = (flo_a - fup_a) + ff_a * sl
        if two_nuts:
            fa_thr += (flo_b - fup_b) + ff_b * sl
        faprev = fa_thr
        # A non-finite value in a position, velocity or the motor torque stays non-finite
        # in every later substep (each is updated as x + increment), so one check per step
        # finds it; S and out are then left as they were at the start of the step.
        if not (math.isfinite(qm) and math.isfinite(q) and math.isfinite(xa) and math.isfinite(xb)
                and math.isfinite(wm) and math.isfinite(dq) and math.isfinite(va)
                and math.isfinite(vb) and math.isfinite(te)):
            S[S_EQ], S[S_EW], S[S_XS], S[S_VS], S[S_NSAMP] = eq0, ew0, xs0, vs0, ns0
            S[S_NREP] = nr0
            return i
        # write the state back once
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
        if not count_phase:
            d_phase = (d_phase + nsub) % d_m
        # limit and home switches from the true nut position at the end of the step (with
        # hysteresis); they act on the next step
        if sw_min:
            sw_min = not (xa > l_min + hyst)
        else:
            sw_min = xa <= l_min
        if sw_max:
            sw_max = not (xa < l_max - hyst)
        else:
            sw_max = xa >= l_max
        home = S[S_HOME] > 0.5
        if home:
            home = not (xa < x_home - hyst)
        else:
            home = xa >= x_home
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
        if ideal_fb:   # the readings of ideal sensors: the truth at the step's end
            S[S_EQ] = qm
            S[S_EW] = wm
            S[S_XS] = xa
            S[S_VS] = va
        # outputs of the last substep
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
        # what the sensors report: an ideal live encoder the true screw angle and rate
        enc_live = P[P_EIDEAL] > 0.5 and P[P_EFRZ] <= 0.5
        if d_phase != 0 and not ideal_fb:   # no drive sample at the step's end: read now
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
        for j in range(REC_STATE):
            rec[i, j] = S[j]
        for j in range(NO):
            rec[i, REC_STATE + j] = out[j]
    return n_steps


@kernel_jit
def step(P, S, out, t_cmd, f_in, dt, nsub, wk, iwk):
    """
    Advance the state S by exactly dt in nsub equal substeps, in torque mode.

    t_cmd: commanded motor torque [N m] in the q sense (it becomes the held
    command); f_in: external axial force on nut A [N] added to the parameter
    one. Returns 0, or 1 if a state became non-finite (S and out are then left
    as they were before the call).
    """
    io = wk[WK_IO:WK_IO + WK_NIO]
    io[0] = t_cmd
    io[1] = f_in
    row = wk[WK_CMD:WK_CMD + N_CMD].reshape((1, N_CMD))
    rec = wk[WK_REC:WK_FLOAT].reshape((1, REC_ROW))   # a scratch record row
    return 0 if _steps(P, S, out, io[0:1], io[1:2], row[0:0], dt, nsub, wk, iwk, rec) == 1 \
        else 1


@kernel_jit
def step_held(P, S, out, f_in, dt, nsub, wk, iwk):
    """
    Advance the state S by exactly dt under the held drive command (S_CMODE .. S_CT).

    f_in: external axial force on nut A [N] added to the parameter one.
    Returns 0, or 1 if a state became non-finite (S and out unchanged).
    """
    io = wk[WK_IO:WK_IO + WK_NIO]
    io[0] = S[S_CT]
    io[1] = f_in
    row = wk[WK_CMD:WK_CMD + N_CMD].reshape((1, N_CMD))
    row[0, 0] = S[S_CMODE]
    row[0, 1] = S[S_CQ]
    row[0, 2] = S[S_CW]
    row[0, 3] = S[S_CT]
    rec = wk[WK_REC:WK_FLOAT].reshape((1, REC_ROW))   # a scratch record row
    return 0 if _steps(P, S, out, io[0:1], io[1:2], row, dt, nsub, wk, iwk, rec) == 1 else 1


@kernel_jit
def run_series(P, S, out, torques, forces, cmds, dt, nsub, wk, iwk, rec):
    """
    Run one step per entry of torques/forces (q sense, N m and N) in one call.

    cmds: drive command rows, shape (0, N_CMD) for torque mode with torques,
    or one row per step (see _steps). After step i, rec[i, :REC_STATE] holds
    S[:REC_STATE] and rec[i, REC_STATE:] the outputs. Returns the number of
    steps done (fewer on a non-finite state).
    """
    return _steps(P, S, out, torques, forces, cmds, dt, nsub, wk, iwk, rec)


refresh_cache()
