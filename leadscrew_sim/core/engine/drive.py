"""
The servo drive of the axis (doc/model.md section 16): timing, the loop law, the command rows.

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
limit switch. A position target further than max_command_jump from the
reference is approached at the velocity limit (capped by max_screw_velocity)
instead of being stepped to (stages.take_command). The velocity loop
(:func:`velocity_loop`) is a PI with conditional integration as anti-windup.
A latched fault (following error, torque limit, injected, or overspeed: the
motor faster than OVERSPEED_MARGIN times max_screw_velocity, checked at each
step's end in every mode) switches the torque off until the model clears it.

This module holds the compiled pieces the kernel calls
(:func:`update_period`, :func:`velocity_loop`), :func:`prepare_commands`
(validates and converts command rows for the model; :func:`command_rows`)
and :func:`effective_rate`. The mode and fault codes are those of
:mod:`leadscrew_sim.core.drive_modes`; the linear design of the gains and
the preset's loop figures are in :mod:`leadscrew_sim.analysis.linear`.
"""
import math

import numpy as np

from ._jit import kernel_jit
from . import layout as L
from ..drive_modes import (FAULT_FOLLOWING_ERROR, FAULT_INJECTED, FAULT_NAMES, FAULT_NONE,
                           FAULT_OVERSPEED, FAULT_TORQUE_LIMIT, MODE_NAMES, MODE_POSITION,
                           MODE_QUICKSTOP, MODE_TORQUE, MODE_VELOCITY)

#: The drive's functions, and the mode and fault codes of :mod:`..drive_modes` the kernel
#: reads from here.
__all__ = ['command_rows', 'effective_rate', 'FAULT_FOLLOWING_ERROR', 'FAULT_INJECTED',
           'FAULT_NAMES', 'FAULT_NONE', 'FAULT_OVERSPEED', 'FAULT_TORQUE_LIMIT', 'MODE_NAMES',
           'MODE_POSITION', 'MODE_QUICKSTOP', 'MODE_TORQUE', 'MODE_VELOCITY', 'prepare_commands',
           'update_period', 'velocity_loop']


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
