"""
Fixed-step integration kernel of the lead screw model (ROS-free, numba-compiled).

Generalised coordinates, all in the "q sense" of doc/model.md section 3
(q = hand sign times theta, so x = r_m tan(lambda) q for every hand):
    u = [motor angle rate, screw angle rate, nut A velocity, half-nut B velocity].

One substep is semi-implicit (symplectic) Euler. Smooth forces (springs,
dampers, gravity, motor) are explicit; every Coulomb-type element (thread
friction of each nut body, screw bearing plus thrust collar, nut guide) is an
implicit velocity-level impulse bounded by its friction limit, found by solving
the small box-constrained LCP exactly. A stuck element keeps its sliding
velocity at zero to round-off, so a self-locking screw does not creep
(no tanh or ramp regularisation).

The servo drive (drive.py, doc/model.md section 16) runs inside the substep
loop: in velocity, position and quick stop mode it updates the held motor
torque command every m substeps; in torque mode it does not run and the
step takes the torque path of the kernel without a drive. A stepper
(stepper.py, doc/model.md section 18; P_STEPPER) replaces both: its stage
runs in every substep and gives the motor torque from its phase currents.

This module holds the integrator _steps and its entry points step,
step_held and run_series, plus workspace(). _steps keeps the state in local
scalars and runs the stages of stages (drive update, forces, friction
impulses, energy, write-back and outputs) on them. The array layouts are in
layout, the friction law in friction, the drive's loop law in drive, the LCP
solvers in lcp; the compile options, shared by all, in _jit.
"""
import math

import numpy as np

from ._jit import kernel_jit, refresh_cache
from .drive import (FAULT_INJECTED, FAULT_NONE, FAULT_OVERSPEED, MODE_POSITION, MODE_TORQUE,
                    update_period)
from .sensors import sample
from .ageing import (aged, ageing_constants, ageing_outputs, ageing_step, flank_gaps,
                     growth_factor, NOT_AGEING, thread_constants)
from .impulses import friction_impulses
from .stepper import (
    command_direction, load_stepper, stepper_constants, stepper_outputs, stepper_substep,
    store_stepper,
)
from .stages import (
    body_constants, drive_constants, drive_update, friction_setup, held_command,
    inverse_masses, load_drive, load_state, smooth_forces, take_command, torque_path,
)
from .write_back import (
    drive_outputs, energy_sums, sensor_outputs, store_drive, store_state, switch_states,
    thread_outputs,
)
from .layout import (
    NO, N_CMD, O_GROW,
    P_CL, P_DJUMP, P_DQ0, P_DRATE, P_DSCALE, P_DSLEW, P_DVMAX, P_DX0, P_EFRZ, P_EIDEAL, P_FEXT,
    P_FINJ, P_HOME, P_HYST, P_JAM, P_JAMX, P_LMAX, P_LMIN, P_DQSD, P_MUC, P_OVS, P_RCOL, P_SFRZ,
    P_K, P_SIDEAL, P_TAU, P_TMAX, P_STEPPER, P_SWMAX, P_TSCALE, P_VFT,
    REC_ROW, REC_STATE,
    S_CMODE, S_CQ, S_CT, S_CW, S_EQ, S_EW, S_HOME, S_JAM, S_NREP, S_NSAMP, S_QM, S_SWMAX,
    S_SWMIN,
    S_VS, S_XA, S_XS,
    WK_CMD, WK_FLOAT, WK_INT, WK_IO, WK_NIO, WK_REC,
)


def workspace():
    """Return the (float, int) scratch arrays that step() and run_series() need."""
    return np.zeros(WK_FLOAT), np.zeros(WK_INT, dtype=np.int64)


@kernel_jit
def _with_friction(lc, fc):
    """Return the friction constants lc (stages.friction_setup) with the law's fc replaced."""
    return (lc[0], lc[1], fc, lc[3], lc[4], lc[5], lc[6], lc[7], lc[8], lc[9], lc[10], lc[11],
            lc[12], lc[13], lc[14], lc[15], lc[16])


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
    stop at jam_x on the side nut A was when it engaged. A stepper (stepper):
    the servo drive never runs; in every substep stepper.stepper_substep
    advances the step generator and the phase currents and gives the motor
    torque (no lag), a latched fault opening the windings; its state slots are
    loaded once per step (load_stepper) and stored at its end.

    Parameters are unpacked once per call into the constant tuples of the
    stages (bc, lc, dc, sc); the state lives in local scalars within a step
    and passes through the stages (stages.py), which also name their
    arguments and units. Locals here (name: meaning [unit]):
      h: substep [s];  hmi_m .. hmi_b: h times the inverse inertia or mass, the velocity
        change per unit force;  alpha: motor torque lag factor per substep [-]
      qm, q [rad], xa, xb [m]; wm, dq [rad/s], va, vb [m/s]: motor and screw
        angles and rates, nut A and half-nut B positions and velocities
        (wm0 .. vb0: at the substep's start);  te: applied motor torque [N m]
      c_*: the held command;  d_*: the drive state (stages.load_drive);
        drive_on: the drive runs this step;  t_sat: torque command [N m];
        q_fb, w_fb: the drive's feedback [rad], [rad/s];  count_phase: d_phase
        is counted substep by substep (the drive runs or a sensor is sampled);
        ideal_fb: both sensors ideal and live (no sampling: the drive reads the
        state, S_EQ .. S_VS get the truth);  eq0 .. nr0: the sensor slots at
        the step's start;  sw_min, sw_max, home: switches;  jam_side: 1 blocks
        +x, -1 blocks -x, 0 no jam
      stepper, stc: the motor is a stepper, its constants (stepper.stepper_constants);
        ia, ib [A], s_pos [rad], s_rate [rad/s], s_k, s_idle [s], ca, sa, i_amp [A]:
        its phase currents, step generator, microstep, standstill time, set point
        direction and current amplitude;  s_lo, s_hi: its rate bounds [rad/s];
        se, ce, wm_p [rad/s]: sin and cos of the rotor's electrical angle in the
        last substep and that substep's starting motor rate (nan: none yet this step)
      ct: the substep's contact forces (stages.smooth_forces); flo_a, fup_a,
        flo_b, fup_b: its flank forces [N];  imp_*, mode_*: friction impulses
        and stick/slip modes (stages.friction_impulses);  faprev: axial thread
        force of the last substep [N];  sum_*: the step's energy sums
        (stages.energy_sums), scaled once at its end into win .. edamp [J]
    """
    h = dt / nsub
    bc = body_constants(P)
    rigid, two_nuts, rt = bc[0], bc[1], bc[2]
    mi_m, mi_s, mi_a, mi_b = inverse_masses(P, rigid)
    hmi_m = h * mi_m   # velocity change per unit force in a substep [s/(kg m^2), s/kg]
    hmi_s = h * mi_s
    hmi_a = h * mi_a
    hmi_b = h * mi_b
    lc = friction_setup(P, h, mi_s, mi_a, mi_b)
    rc, sl, cl = lc[0], lc[1], P[P_CL]
    # ageing (ageing.py): the worn flanks' half gaps, the thread friction at the lubricant
    # state, the screw's thermal strain; updated after each step while a rate is on
    fc0 = lc[2]
    hb = bc[3]
    if aged(P, S):
        ac = ageing_constants(P, dt)
        wr = flank_gaps(S, hb)
        k_tie = 0.5 * P[P_K] if (ac[1] and two_nuts) else 0.0
        lc = _with_friction(lc, thread_constants(P, S, fc0, ac))
        grow = growth_factor(S, ac)
        ageing_outputs(P, S, out, 0.0, grow, S[S_XA])
    else:   # a new axis that does not age: nothing to set up (its outputs are as reset left)
        ac = NOT_AGEING
        wr = (hb, hb, hb, hb)
        k_tie = 0.0
        grow = 0.0
    ageing_on = ac[0]
    grow_on = grow != 0.0
    x_fix = ac[11]
    mu_r_col = P[P_MUC] * P[P_RCOL]
    alpha = 1.0 if P[P_TAU] <= 0.0 else 1.0 - math.exp(-h / P[P_TAU])
    t_scale = P[P_TSCALE]
    jam_on = P[P_JAM] > 0.5
    jam_x = P[P_JAMX]
    # servo drive, switches and sensors
    ncmd = cmds.shape[0]
    d_m = update_period(nsub, dt, P[P_DRATE])
    td = d_m * h
    dc = drive_constants(P, td)
    vmax = P[P_DVMAX]
    sc = (P[P_LMIN], P[P_LMAX], P[P_HOME], P[P_HYST])
    scale_fb = P[P_DSCALE] > 0.5
    q_ref0 = P[P_DQ0]
    x_ref0 = P[P_DX0]
    irt = 1.0 / rt
    beta = 1.0 if P[P_VFT] <= 0.0 else 1.0 - math.exp(-td / P[P_VFT])
    # ideal live sensors read the truth: no sampling in the substeps, the feedback is the state
    ideal_fb = (P[P_EIDEAL] > 0.5 and P[P_EFRZ] <= 0.5 and P[P_SIDEAL] > 0.5
                and P[P_SFRZ] <= 0.5)
    # the stepper (stepper.py) replaces the servo drive and the motor's torque lag
    stepper = P[P_STEPPER] > 0.5
    stc = stepper_constants(P, h)
    s_wmax = P[P_SWMAX]
    ovs = P[P_OVS]
    jump = P[P_DJUMP]
    slew_v = P[P_DSLEW]
    slew_a = P[P_DQSD]
    n_steps = torques.shape[0] if ncmd == 0 else min(torques.shape[0], ncmd)
    for i in range(n_steps):
        fext = P[P_FEXT] + forces[i]
        # the held command: a row of cmds, or torque mode with torques[i]
        c_mode, c_q, c_w, c_t = held_command(S, torques, cmds, i)
        (d_mode, d_qref, d_int, d_tout, d_phase, d_fault, d_tlim, d_qs, d_wqs, d_ferr,
         d_wref) = load_drive(S)
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
        d_mode, d_qref, d_int, d_tlim, d_qs, d_wqs = take_command(
            c_mode, c_q, d_mode, d_qref, d_int, d_tlim, d_qs, d_wqs, S[S_QM], jump, slew_v,
            slew_a, dt)
        # limit and home switches, as the end of the last step left them
        sw_min = S[S_SWMIN] > 0.5
        sw_max = S[S_SWMAX] > 0.5
        drive_on = d_mode != MODE_TORQUE and not stepper
        count_phase = drive_on or not ideal_fb   # else the phase advances once, after the step
        # bounds of the velocity reference: the velocity limit, and 0 toward a tripped
        # switch (rt > 0: w_ref < 0 moves the nut toward -x); one clip applies both
        w_lo = 0.0 if sw_min else -vmax
        w_hi = 0.0 if sw_max else vmax
        w_ff = 0.0 if d_qs != 0 else c_w     # a quick stop and its hold: no feed-forwards
        if d_mode == MODE_POSITION:
            w_ff += d_wqs                    # the rate of a reference approaching its target
        t_ff = 0.0 if d_qs != 0 else c_t
        if drive_on:
            t_sat = d_tout
        else:   # torque mode: the command, saturated; off while faulted or toward a switch
            t_sat = torque_path(c_t, P[P_TMAX], d_fault, sw_min, sw_max)
            d_tout = t_sat
        (qm, q, xa, xb, wm, dq, va, vb, te, t, win, wext, efric, edamp, faprev,
         mode_a, mode_b, mode_c, mode_g, nsearch) = load_state(S)
        ia, ib, s_pos, s_rate, s_k, s_idle = load_stepper(S)
        ca = sa = i_amp = 0.0
        se = ce = 0.0
        wm_p = math.nan   # the first substep computes sin and cos of its angle exactly
        s_lo = s_hi = 0.0
        if stepper:   # no torque: the generator's rate bounds, 0 toward a tripped switch
            t_sat = d_tout = 0.0
            ca, sa = command_direction(s_k, stc)
            s_lo = 0.0 if sw_min else -s_wmax
            s_hi = 0.0 if sw_max else s_wmax
        flo_a = fup_a = flo_b = fup_b = 0.0
        imp_a = imp_b = imp_c = imp_g = 0.0
        sum_in = sum_ext = sum_damp = sum_fric = 0.0
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
                    xg = xa + grow * (xa - x_fix) if grow_on else xa
                    q_fb = q_ref0 + (xg - x_ref0) * irt if scale_fb else qm
                    w_fb = wm
                else:
                    q_fb = q_ref0 + (S[S_XS] - x_ref0) * irt if scale_fb else S[S_EQ]
                    w_fb = S[S_EW]
                (d_mode, d_qref, d_int, d_tout, d_fault, d_tlim, d_qs, d_wqs, d_ferr,
                 d_wref) = drive_update(q_fb, w_fb, w_ff, t_ff, w_lo, w_hi, sw_min, sw_max,
                                        d_mode, d_qref, d_int, d_tout, d_fault, d_tlim, d_qs,
                                        d_wqs, d_ferr, d_wref, dc)
                t_sat = d_tout
            for _ in range(seg):
                if stepper:
                    (te_new, se, ce, ia, ib, s_pos, s_rate, s_k, s_idle, ca, sa, d_mode, d_qref,
                     d_qs, i_amp) = stepper_substep(qm, wm, wm_p, se, ce, ia, ib, s_pos, s_rate,
                                                    s_k, s_idle, ca, sa, d_mode, d_qref, d_qs,
                                                    c_w, s_lo, s_hi, d_fault == FAULT_NONE,
                                                    t_scale, stc)
                    wm_p = wm
                else:
                    te_new = te + alpha * (t_scale * t_sat - te)
                f_m, f_s, f_a, f_b, ct = smooth_forces(qm, q, xa, xb, wm, dq, va, vb, te_new,
                                                       fext, jam_side, jam_x, bc, wr, k_tie)
                flo_a, fup_a, flo_b, fup_b = ct[0], ct[1], ct[2], ct[3]
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
                # friction impulses of thread A, thread B, bearing, guide
                (dq, va, vb, imp_a, imp_b, imp_c, imp_g, mode_a, mode_b, mode_c, mode_g, nact,
                 a_alone, searched) = friction_impulses(
                    dq0, va0, vb0, dq, va, vb, flo_a + fup_a, flo_b + fup_b, faprev, mode_a,
                    mode_b, mode_c, mode_g, lc, wk, iwk)
                if searched:
                    nsearch += 1.0
                if rigid:
                    wm = dq
                if not two_nuts:
                    vb = va
                # positions (symplectic Euler)
                qm_new = qm + h * wm
                q_new = q + h * dq
                xa_new = xa + h * va
                xb_new = xb + h * vb
                sum_in, sum_ext, sum_damp, sum_fric = energy_sums(
                    sum_in, sum_ext, sum_damp, sum_fric, wm0, dq0, va0, vb0, wm, dq, va, vb,
                    te_new, ct, jam_side, imp_a, imp_b, imp_c, imp_g, nact, a_alone, rc, sl, bc)
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
                    if not ideal_fb:   # the scale reads the grown screw's position
                        sample(P, S, qm, wm, xa + grow * (xa - x_fix) if grow_on else xa, va,
                               td, beta, False)
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
        store_state(S, qm, wm, q, dq, xa, va, xb, vb, te, t, win, wext, efric, edamp, faprev,
                    mode_a, mode_b, mode_c, mode_g, nsearch)
        if not count_phase:
            d_phase = (d_phase + nsub) % d_m
        # limit and home switches from the true nut position at the end of the step (with
        # hysteresis); they act on the next step
        sw_min, sw_max, home = switch_states(xa, sw_min, sw_max, S[S_HOME] > 0.5, sc)
        # overspeed: the motor rate at the step's end, in every mode; it acts on the next step
        if ovs > 0.0 and d_fault == FAULT_NONE and abs(wm) > ovs:
            d_fault = FAULT_OVERSPEED
        store_drive(S, c_mode, c_q, c_w, c_t, d_mode, d_qref, d_int, d_tout, d_phase, d_fault,
                    d_tlim, d_qs, d_wqs, d_ferr, d_wref, sw_min, sw_max, home, jam_side)
        if stepper:
            store_stepper(S, ia, ib, s_pos, s_rate, s_k, s_idle)
        xg = xa + grow * (xa - x_fix) if grow_on else xa   # where the scale sees nut A
        if ideal_fb:   # the readings of ideal sensors: the truth at the step's end
            S[S_EQ] = qm
            S[S_EW] = wm
            S[S_XS] = xg
            S[S_VS] = va
        # outputs of the last substep and of the step
        thread_outputs(out, flo_a, fup_a, flo_b, fup_b, ff_a, ff_b, fa_thr, t_br, f_g, dq, va,
                       vb, te, mode_a, mode_b, rc, sl, rt, cl, two_nuts)
        drive_outputs(S, out, nsub, d_mode, d_fault, d_ferr, t_sat, d_wref, drive_on, jam_side)
        # no drive sample at the step's end (and sensors not ideal): the sensors are read now
        sensor_outputs(P, S, out, qm, wm, q, dq, xg, va, d_phase == 0 or ideal_fb, q_ref0,
                       x_ref0, rt)
        if stepper:
            stepper_outputs(P, out, ia, ib, s_k, s_rate, i_amp, rt, q_ref0, x_ref0)
        if ageing_on:   # the step ages the axis; the next step sees the new flanks and friction
            vs_a = rc * dq + sl * va
            vs_b = rc * dq + sl * vb
            heat = ageing_step(S, ac, flo_a / cl, fup_a / cl, flo_b / cl, fup_b / cl, vs_a,
                               vs_b if two_nuts else 0.0,
                               abs(ff_a * vs_a) + abs(ff_b * vs_b) + abs(t_br * dq), dt)
            if ac[1]:
                wr = flank_gaps(S, bc[3])
            if ac[2]:
                lc = _with_friction(lc, thread_constants(P, S, fc0, ac))
            if ac[3]:
                grow = growth_factor(S, ac)
                grow_on = grow != 0.0
            ageing_outputs(P, S, out, heat, grow, xa)
        elif grow_on:
            out[O_GROW] = grow * (xa - x_fix)
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
def report_ageing(P, S, out, dt):
    """Write the ageing outputs O_WLA .. O_GROW of the state S (no step: heat flow 0)."""
    ac = ageing_constants(P, dt)
    ageing_outputs(P, S, out, 0.0, growth_factor(S, ac), S[S_XA])


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
