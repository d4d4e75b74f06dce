"""
The servo drive of the axis (physics.md section 10): modes, faults, timing, the loop law, gains.

The drive runs inside the kernel (kernel._steps): every m substeps it reads
its feedback (q_fb, w_fb: one marked place in the kernel) and updates the
motor torque command, held until the next update. Modes (CiA 402 cyclic
synchronous torque / velocity / position), all in the q sense of layout:

- torque: the command torque, exactly the kernel's torque path (the drive
  block does not run);
- velocity: w_ref = w_cmd, the command torque is a feed-forward;
- position: w_ref = K_p (q_ref - q_fb) + w_cmd (velocity feed-forward);
- quick stop (internal): w_ref ramps from the measured rate to zero at the
  quick stop deceleration, then the drive holds the position reached in
  position mode.

w_ref is clipped to +-velocity_limit in every mode and to 0 toward a tripped
limit switch. The velocity loop (:func:`velocity_loop`) is a PI with
conditional integration as anti-windup. A latched fault (following error,
torque limit, injected) switches the torque off until the model clears it.

This module holds the constants, the compiled pieces the kernel calls
(:func:`update_period`, :func:`velocity_loop`), :func:`prepare_commands`
(validates and converts command rows for the model; :func:`command_rows`,
:func:`mode_code`) and the linear design helpers
(:func:`design_gains`, :func:`loop_response`) that document each preset's
bandwidths.
"""
import math

import numpy as np

from ._jit import kernel_jit
from . import layout as L

MODE_TORQUE = 0         #: cyclic synchronous torque: the command torque
MODE_VELOCITY = 1       #: cyclic synchronous velocity: w_ref = the command rate
MODE_POSITION = 2       #: cyclic synchronous position: P loop on the angle
MODE_QUICKSTOP = 3      #: ramp to standstill, then hold the position (ends in MODE_POSITION)

#: Mode code -> name.
MODE_NAMES = {MODE_TORQUE: 'torque', MODE_VELOCITY: 'velocity', MODE_POSITION: 'position',
              MODE_QUICKSTOP: 'quick_stop'}

FAULT_NONE = 0              #: no fault
FAULT_FOLLOWING_ERROR = 1   #: |q_ref - q_fb| above following_error_limit in position mode
FAULT_TORQUE_LIMIT = 2      #: velocity loop output at +-max_torque longer than torque_limit_time
FAULT_INJECTED = 3          #: latched on request (fault injection)

#: Fault code -> name.
FAULT_NAMES = {FAULT_NONE: 'none', FAULT_FOLLOWING_ERROR: 'following_error',
               FAULT_TORQUE_LIMIT: 'torque_limit', FAULT_INJECTED: 'injected'}

#: Design rule of the shipped gains: T_i = TI_FACTOR / w_v, K_p = w_v / KP_DIVISOR.
TI_FACTOR = 4.0
KP_DIVISOR = 5.0


@kernel_jit
def update_period(nsub, dt, drive_rate):
    """
    Return m, the substeps between drive updates: max(1, round(nsub / (dt drive_rate))).

    The drive updates on the substep grid (h = dt / nsub), so its effective
    period is m h; halves round up.
    """
    m = math.floor(nsub / (dt * drive_rate) + 0.5)
    return max(1, int(m))


@kernel_jit
def velocity_loop(w_ref, w_fb, integ, kv, ki, t_ff, tmax, td):
    """
    Return (T, T_u, I) of one velocity loop update.

    w_ref, w_fb: velocity reference and feedback [rad/s]; integ: the integral I
    of the velocity error [rad]; kv = K_v [N m s/rad]; ki = K_v / T_i [N m/rad]
    (0: no integral); t_ff: torque feed-forward [N m]; tmax: torque limit
    [N m]; td: drive period [s]. T_u = K_v (e + I / T_i) + t_ff with e = w_ref -
    w_fb, evaluated as K_v w_ref - (K_v w_fb - (ki I + t_ff)) so that the
    feedback passes through the fewest operations before the torque (the drive
    update is on the critical path of the substep); T = T_u clipped to +-tmax;
    I advances by e td only while T_u is not saturated or e drives it back
    (conditional integration).
    """
    t_u = kv * w_ref - (kv * w_fb - (ki * integ + t_ff))
    if ki != 0.0:
        e = w_ref - w_fb
        if abs(t_u) < tmax or e * t_u < 0.0:
            integ = integ + e * td
    return min(max(t_u, -tmax), tmax), t_u, integ


@kernel_jit
def prepare_commands(c, hs):
    """
    Validate command rows in place and turn them into the kernel's; return -1 or a bad row.

    c: float64 (n, 4) rows (mode, position [rad], velocity [rad/s], effort
    [N m]) in the theta sense; hs: the hand sign h of q = h theta. A row is bad
    (its index is returned, rows before it are converted) if its mode is not a
    MODE_* code, its mode's command (position, velocity, effort for position,
    velocity, torque mode) is not finite, or a feed-forward is infinite. Else it
    becomes q sense with the unused fields and NaN feed-forwards 0.
    """
    for k in range(c.shape[0]):
        mode = c[k, 0]
        if mode == MODE_POSITION:
            main = c[k, 1]
        elif mode == MODE_VELOCITY:
            main = c[k, 2]
            c[k, 1] = 0.0
        elif mode == MODE_TORQUE:
            main = c[k, 3]
            c[k, 1] = 0.0
            c[k, 2] = 0.0
        elif mode == MODE_QUICKSTOP:
            main = 0.0
            c[k, 1] = 0.0
            c[k, 2] = 0.0
            c[k, 3] = 0.0
        else:
            return k
        if not math.isfinite(main):
            return k
        for j in range(2, 4):
            if math.isnan(c[k, j]):
                c[k, j] = 0.0
            elif not math.isfinite(c[k, j]):
                return k
        c[k, 1] = hs * c[k, 1] + 0.0     # no -0.0 in the unused fields
        c[k, 2] = hs * c[k, 2] + 0.0
        # a torque command keeps its sign bit (as the torque path negates a torque)
        c[k, 3] = hs * c[k, 3] if mode == MODE_TORQUE else hs * c[k, 3] + 0.0
    return -1


def effective_rate(nsub, dt, drive_rate):
    """
    Return the drive's effective update rate [Hz] for steps of dt [s] in nsub substeps.

    Parameters
    ----------
    nsub : int
        Substeps per step.
    dt : float
        Step [s].
    drive_rate : float
        The drive rate asked for [Hz].

    """
    return nsub / (update_period(nsub, dt, drive_rate) * dt)


def total_inertia(p):
    """
    Return J_total = J_m + J_s + (m_n + m_p (+ m_b)) rt^2 [kg m^2], the rigid axis at the motor.

    Parameters
    ----------
    p : ScrewParams
        The parameters.

    """
    rt = p.r_m * math.tan(p.lead_angle)
    return p.motor_inertia + p.screw_inertia + p.moving_mass * rt * rt


def design_gains(p, velocity_bandwidth):
    """
    Return (K_v [N m s/rad], T_i [s], K_p [1/s]) for a velocity-loop bandwidth w_v [rad/s].

    K_v = w_v J_total (the velocity loop's crossover on the rigid axis),
    T_i = TI_FACTOR / w_v, K_p = w_v / KP_DIVISOR: the rule of the shipped presets.

    Parameters
    ----------
    p : ScrewParams
        The parameters (inertias, masses, lead).
    velocity_bandwidth : float
        w_v [rad/s].

    """
    w = float(velocity_bandwidth)
    return w * total_inertia(p), TI_FACTOR / w, w / KP_DIVISOR


def closed_loop(j, kv, ti, kp, td):
    """
    Return (A, b_pos, b_vel): the rigid axis under the drive, sampled at the drive period.

    State [q, w, I] just before a drive update; the torque is held over td
    (zero-order hold: exact for the plant J s^2 between updates). b_pos is the
    input vector of q_ref in position mode, b_vel that of w_ref in velocity
    mode; A is the position-mode matrix (the velocity mode's has K_p = 0, and
    its [w, I] block A[1:, 1:] is the velocity loop on its own).

    Parameters
    ----------
    j : float
        Inertia [kg m^2].
    kv : float
        Velocity gain [N m s/rad].
    ti : float
        Integral time [s]; 0: no integral.
    kp : float
        Position gain [1/s]; 0 for the velocity loop alone.
    td : float
        Drive period [s].

    """
    gi = kv / ti if ti > 0.0 else 0.0
    # T = kv e + gi I with e = kp (q_ref - q) - w (position) or w_ref - w (velocity)
    de = np.array([-kp, -1.0, 0.0])            # de/dx
    dt_dx = kv * de + np.array([0.0, 0.0, gi])  # dT/dx
    hold = np.array([td * td / (2.0 * j), td / j, 0.0])
    a = np.array([[1.0, td, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])
    a = a + np.outer(hold, dt_dx)
    if ti > 0.0:
        a[2] += td * de
    e_in = np.array([0.0, 0.0, td if ti > 0.0 else 0.0])
    b_pos = hold * kv * kp + e_in * kp
    b_vel = hold * kv + e_in
    return a, b_pos, b_vel


def loop_response(p, dt=1e-3, nsub=None):
    """
    Return the linear design figures of the drive gains of p on the rigid, frictionless axis.

    Parameters
    ----------
    p : ScrewParams
        The parameters (gains, drive rate, inertias).
    dt : float
        Step [s] (sets the substep grid and so the effective drive period).
    nsub : int, optional
        Substeps per step; default the model's for p and dt.

    Returns
    -------
    dict
        j_total [kg m^2]; w_v = K_v / J_total [rad/s]; drive_rate [Hz] (effective);
        f_vel, f_pos: -3 dB bandwidths of the velocity loop (w / w_ref) and the
        position loop (q / q_ref) [Hz], sampled at the drive period;
        overshoot [-] and settling_time (2 %) [s] of a small position step.

    """
    if nsub is None:
        from .packing import auto_substep
        nsub = max(1, math.ceil(dt / auto_substep(p) - 1e-9))
    m = update_period(nsub, dt, p.drive_rate)
    td = m * dt / nsub
    j = total_inertia(p)
    kv, ti, kp = p.velocity_gain, p.velocity_integral_time, p.position_gain
    a_pos, b_pos, _ = closed_loop(j, kv, ti, kp, td)
    a_vel, _, b_vel = closed_loop(j, kv, ti, 0.0, td)

    def bandwidth(a, b, out):
        eye = np.eye(len(b))
        dc = out @ np.linalg.solve(eye - a, b)
        w_nyq = math.pi / td
        ws = np.geomspace(1e-2, w_nyq, 4000)
        mags = np.array([abs(out @ np.linalg.solve(np.exp(1j * w * td) * eye - a, b)) for w in ws])
        low = np.nonzero(mags < abs(dc) / math.sqrt(2.0))[0]
        return ws[low[0]] / (2 * math.pi) if len(low) else w_nyq / (2 * math.pi)

    x = np.zeros(3)
    ys = []
    for _ in range(int(math.ceil(10.0 / (max(kp, 1e-3) * td)))):
        ys.append(x[0])
        x = a_pos @ x + b_pos
        if len(ys) > 200000:
            break
    ys = np.array(ys)
    outside = np.nonzero(np.abs(ys - 1.0) > 0.02)[0]
    settle = (outside[-1] + 1) * td if len(outside) else 0.0
    return dict(j_total=j, w_v=kv / j, drive_rate=1.0 / td,
                f_vel=bandwidth(a_vel[1:, 1:], b_vel[1:], np.array([1.0, 0.0])),
                f_pos=bandwidth(a_pos, b_pos, np.array([1.0, 0.0, 0.0])),
                overshoot=max(0.0, ys.max() - 1.0), settling_time=settle)


def mode_code(mode):
    """
    Return the MODE_* code of a mode code or name; raise ValueError otherwise.

    Parameters
    ----------
    mode : int or str
        A MODE_* code or its name in :data:`MODE_NAMES`.

    """
    if isinstance(mode, str):
        for code, name in MODE_NAMES.items():
            if name == mode:
                return code
        raise ValueError(f'unknown drive mode {mode!r} (known: {", ".join(MODE_NAMES.values())})')
    if isinstance(mode, bool) or mode not in MODE_NAMES:
        raise ValueError(f'unknown drive mode {mode!r} (codes: {sorted(MODE_NAMES)})')
    return int(mode)


def command_rows(commands, hand_sign):
    """
    Return validated command rows (n, 4) in the q sense, unused fields 0.

    Parameters
    ----------
    commands : array_like of float, shape (n, 4)
        (mode, position [rad], velocity [rad/s], effort [N m]) rows, theta sense.
    hand_sign : float
        h of q = h theta.

    """
    c = np.array(commands, dtype=float)
    if c.ndim != 2 or c.shape[1] != L.N_CMD:
        raise ValueError(f'commands must have shape (n, {L.N_CMD}): mode, position, '
                         f'velocity, effort; got {c.shape}')
    original = c.copy() if len(c) < 2 else None
    bad = prepare_commands(c, hand_sign)
    if bad >= 0:
        row = (original if original is not None else np.array(commands, float))[bad]
        mode = row[0]
        if mode not in MODE_NAMES:
            raise ValueError(f'command {bad}: unknown drive mode {mode!r} '
                             f'(codes: {sorted(MODE_NAMES)})')
        need = {MODE_POSITION: 'position', MODE_VELOCITY: 'velocity',
                MODE_TORQUE: 'effort'}.get(int(mode))
        raise ValueError(f'command {bad}: mode {MODE_NAMES[int(mode)]} needs a finite '
                         f'{need} and finite feed-forwards; got {list(row)}')
    return c
