"""
Kernel stages, compiled: a substep's energy sums, a step's write-back and outputs.

Conventions as in :mod:`.stages`.
"""
from ._jit import kernel_jit
from .drive import MODE_POSITION
from .sensors import readings
from .layout import (
    O_CONTA, O_CONTB, O_DFAULT, O_DFERR, O_DMODE, O_DTCMD, O_DWREF, O_FAX, O_FFA, O_FFB, O_FG,
    O_HOME, O_JAM, O_JQ, O_JV, O_JW, O_JX, O_NLA, O_NLB, O_NSUB, O_NUA, O_NUB, O_STICKA,
    O_STICKB, O_SWMAX, O_SWMIN, O_TBR, O_TE, O_TTH, O_VSA, O_VSB, P_EFRZ, P_EIDEAL, P_SFIT,
    P_SFRZ, P_SIDEAL, S_CMODE, S_CQ, S_CT, S_CW, S_DFAULT, S_DFERR, S_DINT, S_DMODE, S_DPHASE,
    S_DQ, S_DQREF, S_DQS, S_DTLIM, S_DTOUT, S_DWQS, S_DWREF, S_EDAMP, S_EFRIC, S_EQ, S_EW,
    S_FAPREV, S_HOME, S_JAM, S_MODE0, S_NSEARCH, S_Q, S_QM, S_SWMAX, S_SWMIN, S_T, S_TE, S_VA,
    S_VB, S_VS, S_WEXT, S_WIN, S_WM, S_XA, S_XB, S_XS,
)


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
