"""
The stepper motor and its driver (doc/model.md section 18), compiled stages of the kernel.

A two-phase hybrid stepper with N_r rotor teeth: electrical angle theta_e =
N_r (q_m - q_0), with q_0 the motor angle of the initial state (the driver
powers up there, at microstep 0). In the q sense of layout (the phase B
current is h times the physical one, so the equations keep their form):

- L di_a/dt = v_a - R i_a + K_m w_m sin(theta_e)
- L di_b/dt = v_b - R i_b - K_m w_m cos(theta_e)
- T_e = K_m (-i_a sin(theta_e) + i_b cos(theta_e)) - T_d sin(4 theta_e) - B w_m

The driver: the step generator (:func:`step_generator`) turns the held
command into a commanded motor angle, quantised to microsteps k (angle q_0 +
k step_angle / microsteps); the current set points are i_a* = I cos(N_r k
microstep), i_b* = I sin(N_r k microstep), with I the run current, or the hold
current once the command has stood still for the hold delay. Each phase's
averaged chopper applies v = clip(R i* + K_i (i* - i), -V, +V) (the R i*
feed-forward makes the standstill current exactly i*; no back-EMF
feed-forward); :func:`_phase` integrates the current over a substep in
closed form (exponential, so any substep is stable). Disabled (a latched
fault) the bridge is off: each current decays against the supply to zero
(fast decay) and the windings stay open (i = 0).

Modes (the servo drive's codes, :mod:`..drive_modes`): position, a trapezoid
to the target (max step rate, acceleration); velocity, the rate ramped to the
command; quick stop, the rate ramped to 0, then a position hold; torque mode
(the state after reset, no torque command is taken) holds the position.

The kernel (kernel._steps) calls :func:`stepper_substep` in every substep
when the parameter vector says stepper (P_STEPPER), instead of the servo
motor's torque lag; :func:`load_stepper` and :func:`store_stepper` move the
state slots S_IA .. S_SIDLE to and from local scalars once per step, and
:func:`stepper_outputs` reports the step.
"""
import math

from ._jit import kernel_jit
from ..drive_modes import MODE_POSITION, MODE_QUICKSTOP, MODE_VELOCITY
from .stages import inline_jit
from .layout import (
    O_DTCMD, O_DWREF, O_IA, O_IB, O_ISET, O_JQ, O_JV, O_JW, O_JX, O_SCMD, O_SRATE, P_BROT,
    P_DQ0, P_IHOLD, P_IRUN, P_KI, P_KM, P_LPH, P_NR, P_RPH, P_SACC, P_SFIT, P_SNOENC, P_SWMAX,
    P_TDET, P_THOLD, P_USTEP, P_VSUP, S_IA, S_IB, S_SIDLE, S_SK, S_SPOS, S_SRATE,
)


@kernel_jit
def stepper_constants(P, h):
    """
    Return stc, the stepper's constants for substeps of h [s].

    stc = (nr, ustep, q0, km, i_run, i_hold, t_hold, r, ki, v, t_det, wmax, acc, b_rot,
    h, tau_f, tau_s, e_fast, e_slow, inv_rk, ki_rk, inv_r, inv_ki, inv_tau_f, inv_tau_s,
    c_us, s_us, nh_1, nh_2, tau_sf, h_f, g_fast, g_emf, inv_us): rotor teeth [-]; microstep
    angle [rad]; the motor angle of microstep 0 [rad]; K_m [N m/A]; run and hold current
    [A]; hold delay [s]; R [ohm]; K_i [V/A]; supply voltage [V]; detent torque [N m];
    largest rate [rad/s] and acceleration [rad/s^2] of the step generator; rotor damping
    [N m s/rad]; the substep [s]; the current's time constants with the loop closed, L /
    (R + K_i), and with the voltage clipped, L / R [s], and their decay factors over a
    substep; 1 / (R + K_i) [A/V], K_i / (R + K_i) [-], 1 / R and 1 / K_i [A/V], 1 /
    tau_f and 1 / tau_s [1/s]; cos and sin of a microstep's electrical angle; 1.5 N_r h
    and 0.5 N_r h [s] (the electrical angle's advance over a substep is nh_1 w_m - nh_2
    w_m of the last substep); tau_s / tau_f and h / tau_f [-]; 1 - e_fast [-] and (1 -
    e_fast) / (R + K_i) [A/V] (the linear zone's decay written as i e_fast + i* g_fast +
    emf g_emf); 1 / the microstep angle [1/rad].
    """
    r = P[P_RPH]
    ki = P[P_KI]
    ell = P[P_LPH]
    tau_f = ell / (r + ki)
    tau_s = ell / r
    return (P[P_NR], P[P_USTEP], P[P_DQ0], P[P_KM], P[P_IRUN], P[P_IHOLD], P[P_THOLD], r, ki,
            P[P_VSUP], P[P_TDET], P[P_SWMAX], P[P_SACC], P[P_BROT], h, tau_f, tau_s,
            math.exp(-h / tau_f), math.exp(-h / tau_s), 1.0 / (r + ki), ki / (r + ki), 1.0 / r,
            1.0 / ki, 1.0 / tau_f, 1.0 / tau_s, math.cos(P[P_NR] * P[P_USTEP]),
            math.sin(P[P_NR] * P[P_USTEP]), 1.5 * (P[P_NR] * h), 0.5 * (P[P_NR] * h),
            tau_s / tau_f, h / tau_f, 1.0 - math.exp(-h / tau_f),
            (1.0 - math.exp(-h / tau_f)) / (r + ki), 1.0 / P[P_USTEP])


@kernel_jit
def load_stepper(S):
    """Return the stepper's state (ia, ib [A], s_pos [rad], s_rate [rad/s], s_k, s_idle [s])."""
    return S[S_IA], S[S_IB], S[S_SPOS], S[S_SRATE], S[S_SK], S[S_SIDLE]


@kernel_jit
def store_stepper(S, ia, ib, s_pos, s_rate, s_k, s_idle):
    """Write the stepper's state (the scalars of load_stepper) back into S."""
    S[S_IA] = ia
    S[S_IB] = ib
    S[S_SPOS] = s_pos
    S[S_SRATE] = s_rate
    S[S_SK] = s_k
    S[S_SIDLE] = s_idle


@kernel_jit
def command_direction(s_k, stc):
    """Return (cos, sin) of the commanded electrical angle N_r k microstep of microstep s_k."""
    th = stc[0] * (s_k * stc[1])
    return math.cos(th), math.sin(th)


@kernel_jit
def step_generator(s_pos, s_rate, d_mode, d_qref, c_w, s_lo, s_hi, wmax, acc, h):
    """
    Advance the step generator by a substep h [s]; return (s_pos [rad], s_rate [rad/s], stopped).

    s_pos, s_rate: commanded motor angle (unquantised) and rate; d_mode,
    d_qref [rad]: the active mode and position target; c_w [rad/s]: the
    velocity command; s_lo, s_hi [rad/s]: bounds of the rate (0 toward a
    tripped limit switch, which also stops a motion toward it at once); wmax,
    acc: largest rate [rad/s] and acceleration [rad/s^2]. Position mode runs
    the trapezoid: the rate aims at sign(d) min(wmax, sqrt(2 acc |d|)) for the
    distance d to the target, within acc h of its last value, and lands on
    the target when it reaches it slowly enough; velocity mode ramps the rate
    to the command; any other mode to 0. stopped: a quick stop or hold is at
    rest.
    """
    a_h = acc * h
    d = 0.0
    if d_mode == MODE_POSITION:
        d = d_qref - s_pos
        v_des = min(math.sqrt(2.0 * acc * abs(d)), wmax)
        if d < 0.0:
            v_des = -v_des
    elif d_mode == MODE_VELOCITY:
        v_des = min(max(c_w, -wmax), wmax)
    else:
        v_des = 0.0
    v_des = min(max(v_des, s_lo), s_hi)
    s_rate = s_rate + min(max(v_des - s_rate, -a_h), a_h)
    s_rate = min(max(s_rate, s_lo), s_hi)
    s_pos = s_pos + h * s_rate
    if d_mode == MODE_POSITION:
        if (d_qref - s_pos) * d <= 0.0 and abs(s_rate) <= 2.0 * a_h:   # at the target
            s_pos = d_qref
            s_rate = 0.0
    return s_pos, s_rate, s_rate == 0.0 and d_mode != MODE_VELOCITY


@kernel_jit
def _phase_pieces(i, i_set, emf, stc):
    """
    Return a phase current [A] after a substep h [s] of the averaged chopper (i_set, emf held).

    L di/dt = clip(R i_set + K_i (i_set - i), -v, v) - R i + emf, solved exactly:
    piecewise exponential, toward i_set + emf / (R + K_i) with time constant
    tau_f = L / (R + K_i) while the voltage is in the linear zone, toward
    (+-v + emf) / R with tau_s = L / R while it is clipped; a substep that
    crosses the zone's edge is split at the crossing (at most three pieces).
    stc: stepper_constants. :func:`_phase` takes the substeps that stay in one
    zone without this.
    """
    r, ki, v, h = stc[7], stc[8], stc[9], stc[14]
    inv_rk, inv_r, inv_ki, inv_tau_f, inv_tau_s = stc[19], stc[21], stc[22], stc[23], stc[24]
    ri = r * i_set
    u = ri + ki * (i_set - i)
    zone = 0 if -v <= u <= v else (1 if u > 0.0 else -1)
    i_pv = i_set + (ri - v) * inv_ki     # u = +v here; below it the voltage clips at +v
    i_nv = i_set + (ri + v) * inv_ki     # u = -v here; above it at -v
    left = h
    for _ in range(3):
        if zone == 0:
            target = i_set + emf * inv_rk
            rate = inv_tau_f
            decay = stc[17]
            edge = i_pv if target < i_pv else (i_nv if target > i_nv else target)
            nxt = 1 if target < i_pv else -1
        elif zone == 1:
            target = (v + emf) * inv_r
            rate = inv_tau_s
            decay = stc[18]
            edge = i_pv if target > i_pv else target
            nxt = 0
        else:
            target = (emf - v) * inv_r
            rate = inv_tau_s
            decay = stc[18]
            edge = i_nv if target < i_nv else target
            nxt = 0
        if edge == target or (edge - target) * (i - target) <= 0.0:
            crossing = left + 1.0     # the target lies in the zone: no crossing
        else:
            ratio = (i - target) / (edge - target)
            crossing = math.log(ratio) / rate if ratio > 1.0 else 0.0
        if crossing >= left:
            if left == h:
                return target + (i - target) * decay
            return target + (i - target) * math.exp(-left * rate)
        i = edge
        left -= crossing
        zone = nxt
    return i


@inline_jit
def _phase(i, i_set, emf, stc):
    """
    Return a phase current [A] after a substep of the averaged chopper: :func:`_phase_pieces`.

    Inlined: the common substep, whose current stays in the zone it starts in
    (its target lies there), is one exponential decay; so is the substep that
    starts clipped and crosses into the linear zone, whose target lies there
    (the two pieces of :func:`_phase_pieces` in closed form: a log and an exp).
    Only the other substeps that cross the edge of the linear zone call
    :func:`_phase_pieces`. stc: stepper_constants.
    """
    r = stc[7]
    ki = stc[8]
    v = stc[9]
    ri = r * i_set
    u = ri + ki * (i_set - i)
    if -v <= u <= v:
        if -v <= ri - stc[20] * emf <= v:        # the voltage at the target
            # target + (i - target) e_fast, target = i_set + emf / (R + K_i)
            return (i * stc[17] + i_set * stc[31]) + emf * stc[32]
        return _phase_pieces(i, i_set, emf, stc)
    if u > 0.0:
        target = (v + emf) * stc[21]
        if ri + ki * (i_set - target) >= v:
            return target + (i - target) * stc[18]
        edge = i_set + (ri - v) * stc[22]
        beyond = target > edge
    else:
        target = (emf - v) * stc[21]
        if ri + ki * (i_set - target) <= -v:
            return target + (i - target) * stc[18]
        edge = i_set + (ri + v) * stc[22]
        beyond = target < edge
    # clipped, toward a target beyond the edge of the linear zone, whose own target lies in
    # it: the two pieces of _phase_pieces, the second's decay exp(-(h - t_c) / tau_f) with
    # the crossing time t_c = tau_s ln(ratio) written as exp(ln(ratio) tau_s / tau_f - h /
    # tau_f)
    t_f = i_set + emf * stc[19]
    if (beyond and (edge - target) * (i - target) > 0.0
            and i_set + (ri - v) * stc[22] <= t_f <= i_set + (ri + v) * stc[22]):
        ratio = (i - target) / (edge - target)
        lr = math.log(ratio) if ratio > 1.0 else 0.0
        if lr * stc[16] < stc[14]:
            return t_f + (edge - t_f) * math.exp(lr * stc[29] - stc[30])
    return _phase_pieces(i, i_set, emf, stc)


@kernel_jit
def _open(i, emf, r, v, e_slow):
    """Return a phase current [A] after a substep with the bridge off: decay to 0, then open."""
    if i == 0.0:
        return 0.0
    i_ss = ((-v if i > 0.0 else v) + emf) / r
    i_new = i_ss + (i - i_ss) * e_slow
    return 0.0 if i_new * i <= 0.0 else i_new


@inline_jit
def stepper_substep(qm, wm, wm_p, se, ce, ia, ib, s_pos, s_rate, s_k, s_idle, ca, sa, d_mode,
                    d_qref, d_qs, c_w, s_lo, s_hi, enabled, t_scale, stc):
    """
    Run the stepper's driver and motor for one substep; return the motor torque and state.

    qm [rad], wm [rad/s]: rotor angle and rate at the substep's start; wm_p
    [rad/s], se, ce: the rate at the last substep's start and the sin and cos
    of the electrical angle it used (wm_p nan: none, at a step's first
    substep; the angle then is computed exactly, else rotated from theirs by
    the small angle qm moved since, see the body); ia, ib
    [A]: phase currents; s_pos [rad], s_rate [rad/s], s_k, s_idle [s]: step
    generator position and rate, microstep index, standstill time; ca, sa:
    cos and sin of the commanded electrical angle (of s_k: a single microstep
    rotates them by a microstep's angle, the kernel recomputes them exactly at
    each step's start, :func:`command_direction`); d_mode, d_qref
    [rad], d_qs: mode, position target and quick stop state (load_drive);
    c_w [rad/s]: velocity command; s_lo, s_hi [rad/s]: rate bounds
    (step_generator); enabled: no fault latched (else the bridge is off and
    the generator stands); t_scale: share of the electromagnetic torque a
    weakened motor delivers; stc: stepper_constants.

    Returns (te [N m], se, ce, ia, ib, s_pos, s_rate, s_k, s_idle, ca, sa,
    d_mode, d_qref, d_qs, i_amp [A]): se, ce the sin and cos of this
    substep's electrical angle; te = t_scale K_m (-i_a sin theta_e + i_b cos
    theta_e) - T_d sin(4 theta_e) - B w_m with the currents at the substep's
    end; a quick stop at rest becomes a position hold there; i_amp is the
    current amplitude set (0 disabled).
    """
    (nr, ustep, q0, km, i_run, i_hold, t_hold, r, ki, v, t_det, wmax, acc, b_rot, h, tau_f,
     tau_s, e_fast, e_slow, inv_rk, ki_rk, inv_r, inv_ki, inv_tau_f, inv_tau_s, c_us,
     s_us, nh_1, nh_2, tau_sf, h_f, g_fast, g_emf, inv_us) = stc
    kt = t_scale * km
    s_mid = s_pos
    if enabled:
        s_pos, s_rate, stopped = step_generator(s_pos, s_rate, d_mode, d_qref, c_w, s_lo,
                                                s_hi, wmax, acc, h)
        s_mid = 0.5 * (s_mid + s_pos)
        if d_mode == MODE_QUICKSTOP:
            d_qs = 2
            if stopped:   # standstill: hold the position reached
                d_mode = MODE_POSITION
                d_qref = s_pos
    else:
        s_rate = 0.0
    # the microstep and the rotor's electrical angle at the substep's middle
    k = float(math.floor((s_mid - q0) * inv_us + 0.5))
    if k != s_k:
        s_idle = 0.0
        if k == s_k + 1.0:      # one microstep: rotate the direction (exact again each step)
            ca, sa = ca * c_us - sa * s_us, sa * c_us + ca * s_us
        elif k == s_k - 1.0:
            ca, sa = ca * c_us + sa * s_us, sa * c_us - ca * s_us
        else:
            ca, sa = command_direction(k, stc)
        s_k = k
    else:
        s_idle += h
    # sin and cos of theta_e = N_r (q_m + h w_m / 2 - q_0): rotated from the last substep's
    # (se, ce at the rate wm_p; qm advanced by h wm since) by the small angle
    # d = N_r h (1.5 w_m - 0.5 w_p) (Taylor polynomials), exactly at a step's first substep
    # (wm_p nan) or after a large angle
    d = nh_1 * wm - nh_2 * wm_p
    if abs(d) <= 0.125:
        z = d * d
        z2 = z * z
        sd = d + (d * z) * ((-0.16666666666666666 + z * 0.008333333333333333)
                            + z2 * (-0.0001984126984126984 + z * 2.7557319223985893e-06))
        cd = 1.0 + z * ((-0.5 + z * 0.041666666666666664)
                        + z2 * ((-0.001388888888888889 + z * 2.48015873015873e-05)
                                + z2 * -2.755731922398589e-07))
        s = se * cd + ce * sd
        c = ce * cd - se * sd
    else:
        th_e = nr * (qm + 0.5 * h * wm - q0)
        s = math.sin(th_e)
        c = math.cos(th_e)
    emf_a = km * wm * s
    emf_b = -km * wm * c
    if enabled:
        i_amp = i_hold if s_idle >= t_hold else i_run
        ia = _phase(ia, i_amp * ca, emf_a, stc)
        ib = _phase(ib, i_amp * sa, emf_b, stc)
    else:
        i_amp = 0.0
        ia = _open(ia, emf_a, r, v, e_slow)
        ib = _open(ib, emf_b, r, v, e_slow)
    te = kt * (ib * c - ia * s) - (t_det * (4.0 * s * c * (c * c - s * s)) + b_rot * wm)
    return te, s, c, ia, ib, s_pos, s_rate, s_k, s_idle, ca, sa, d_mode, d_qref, d_qs, i_amp


@kernel_jit
def stepper_outputs(P, out, ia, ib, s_k, s_rate, i_amp, rt, q_ref0, x_ref0):
    """
    Write the stepper's outputs of the step into out, and what the controller believes.

    ia, ib [A]: phase currents; s_k, s_rate [rad/s]: microstep index and
    rate of the step generator; i_amp [A]: current amplitude set; rt [m/rad],
    q_ref0 [rad], x_ref0 [m]: the lead mapping. Without an encoder
    (P_SNOENC) the screw joint reports the commanded angle and rate, and
    without a linear scale the nut joint reports them through the lead.
    """
    q_cmd = P[P_DQ0] + s_k * P[P_USTEP]
    out[O_IA] = ia
    out[O_IB] = ib
    out[O_SCMD] = q_cmd
    out[O_SRATE] = s_rate
    out[O_ISET] = i_amp
    out[O_DTCMD] = 0.0
    out[O_DWREF] = s_rate
    if P[P_SNOENC] > 0.5:
        out[O_JQ] = q_cmd
        out[O_JW] = s_rate
        if P[P_SFIT] <= 0.5:
            out[O_JX] = x_ref0 + (q_cmd - q_ref0) * rt
            out[O_JV] = s_rate * rt
