"""
The servo drive's side of the model: a mix-in of :class:`.model.LeadScrewModel`.

:meth:`DriveControl.command` sets the held command (converted by the rule of
a command row, :func:`.engine.drive.prepare_commands`) that
:meth:`~DriveControl.advance_held` follows; the latched fault is cleared or
injected here, and the drive's status, held command and switches are read
in the theta sense. :meth:`~DriveControl.nut_to_motor` and
:meth:`~DriveControl.motor_to_nut` map the drive's position frame.
"""
import math

import numpy as np

from . import drive_modes as DM
from .engine import drive as D
from .engine import kernel as K
from .engine import layout as L
from .engine.packing import auto_substep
from .output import lost_full_steps


class DriveControl:
    """The drive commands and status of the model (uses its state, parameters and kernel)."""

    def command(self, mode, position=math.nan, velocity=math.nan, effort=0.0):
        """
        Set the held drive command that :meth:`advance_held` follows, from the next step on.

        Parameters
        ----------
        mode : int or str
            ``drive_modes.MODE_TORQUE`` (0, 'torque'), ``MODE_VELOCITY`` (1, 'velocity'),
            ``MODE_POSITION`` (2, 'position') or ``MODE_QUICKSTOP`` (3,
            'quick_stop': ramp to standstill at ``quick_stop_deceleration``, then
            hold the position reached; repeating it does not restart the ramp).
        position : float
            Target motor (screw) angle [rad], theta sense, in the frame of
            :meth:`nut_to_motor`; required in position mode, unused otherwise.
        velocity : float
            Motor rate [rad/s], theta sense: the command in velocity mode, the
            velocity feed-forward in position mode (NaN: none).
        effort : float
            Motor torque [N m], theta sense: the command in torque mode, the torque
            feed-forward in velocity and position mode (NaN: none).

        Raises
        ------
        ValueError
            If the mode is unknown or its command is not finite, or a stepper is
            given a torque command other than 0 N m (nothing changes).

        """
        code = DM.mode_code(mode)
        row = np.array([[code, float(position), float(velocity), float(effort)]])
        if D.prepare_commands(row, self.params.hand_sign) >= 0:   # the rule of a command row
            raise ValueError(f'mode {DM.MODE_NAMES[code]} needs a finite '
                             f'{("effort", "velocity", "position", "")[code]} and finite '
                             f'feed-forwards; got position={position!r}, velocity={velocity!r}, '
                             f'effort={effort!r}')
        self._refuse_torque(row)
        self.state[[L.S_CMODE, L.S_CQ, L.S_CW, L.S_CT]] = row[0]

    def advance_held(self, external_force=0.0):
        """
        Advance by one step of ``dt`` under the held drive command (see :meth:`command`).

        Parameters
        ----------
        external_force : float
            Axial force on the nut along +x [N], in addition to the parameter.

        Raises
        ------
        ValueError
            If the force is not finite.
        SimulationFault
            If the state became non-finite (the state is the one before the step).

        """
        if not math.isfinite(external_force):
            raise ValueError(f'non-finite input: external_force={external_force!r} N')
        self._check_fault()
        rc = K.step_held(self._P, self.state, self.out, float(external_force), self.dt,
                         self.nsub, self._wk, self._iwk)
        if rc != 0:
            self._fail(f'non-finite state at t={self.state[L.S_T]:.6f} s (drive mode '
                       f'{int(self.state[L.S_DMODE])}); integration stopped')

    def clear_fault(self):
        """
        Clear a latched drive fault: the drive holds the current position (position mode, I = 0).

        The held command becomes that position hold, so the axis does not jump;
        a new command takes over from the next step. A stepper's driver is
        enabled again at the microstep it was at (its step generator holds
        there): a rotor that moved while the windings were open snaps to the
        nearest rest of that microstep, a whole number of electrical cycles away.

        Returns
        -------
        int
            The fault code that was latched (``drive_modes.FAULT_NONE`` if none: then
            nothing changes).

        """
        s = self.state
        code = int(s[L.S_DFAULT])
        if code == DM.FAULT_NONE:
            return code
        q_fb = self._feedback_angle()
        if self._P[L.P_STEPPER] > 0.5:
            q_fb = s[L.S_SPOS]
            s[L.S_SRATE] = 0.0
        s[[L.S_DFAULT, L.S_DINT, L.S_DTLIM, L.S_DQS, L.S_DFERR, L.S_DTOUT]] = 0.0
        s[L.S_DMODE] = s[L.S_CMODE] = DM.MODE_POSITION
        s[L.S_DQREF] = s[L.S_CQ] = q_fb
        s[L.S_CW] = s[L.S_CT] = 0.0
        return code

    def inject_fault(self):
        """Latch ``drive_modes.FAULT_INJECTED`` unless one is latched (torque off till cleared)."""
        if int(self.state[L.S_DFAULT]) == DM.FAULT_NONE:
            self.state[L.S_DFAULT] = DM.FAULT_INJECTED

    def drive_status(self):
        """
        Return the drive's state after the last step.

        Returns
        -------
        dict
            mode (``drive_modes.MODE_*`` code) and mode_name; fault (``drive_modes.FAULT_*``
            code) and fault_name; limit_min, limit_max, home (switch states,
            bool); following_error: target less feedback angle [rad], theta sense
            (0 outside position mode); effective_drive_rate [Hz] (the substep grid's
            rate nearest to ``drive_rate``); drive_torque: the drive's torque command
            [N m] and velocity_reference [rad/s], theta sense.

        """
        s, hs = self.state, self.params.hand_sign
        mode, fault = int(s[L.S_DMODE]), int(s[L.S_DFAULT])
        return dict(
            mode=mode, mode_name=DM.MODE_NAMES[mode], fault=fault,
            fault_name=DM.FAULT_NAMES[fault], limit_min=bool(s[L.S_SWMIN] == 1.0),
            limit_max=bool(s[L.S_SWMAX] == 1.0), home=bool(s[L.S_HOME] == 1.0),
            following_error=float(hs * s[L.S_DFERR]) + 0.0 if mode == DM.MODE_POSITION else 0.0,
            effective_drive_rate=D.effective_rate(self.nsub, self.dt, self.params.drive_rate),
            drive_torque=float(hs * s[L.S_DTOUT]) + 0.0,
            velocity_reference=float(hs * s[L.S_DWREF]) + 0.0 if mode != DM.MODE_TORQUE else 0.0)

    def stepper_status(self):
        """
        Return the stepper's state after the last step (None for a servo drive).

        Returns
        -------
        dict or None
            enabled (bool: no fault latched, the bridge on); step_position [rad]
            and step_rate [rad/s], theta sense: the motor angle (its microstep)
            and rate the step generator commands, what the controller believes;
            microstep: the index of the commanded microstep from the initial
            state; phase_current_a, phase_current_b [A] and current_set [A] (run
            or hold current, 0 disabled); lost_full_steps: the full steps the rotor
            lost against the command, a multiple of 4, simulation truth that a
            real driver cannot know (:func:`.output.lost_full_steps`).

        """
        if self._P[L.P_STEPPER] <= 0.5:
            return None
        s, o, hs = self.state, self.out, self.params.hand_sign
        position = hs * float(o[L.O_SCMD])
        return dict(
            enabled=int(s[L.S_DFAULT]) == DM.FAULT_NONE, step_position=position,
            step_rate=hs * float(s[L.S_SRATE]) + 0.0, microstep=int(hs * s[L.S_SK]),
            phase_current_a=float(o[L.O_IA]), phase_current_b=hs * float(o[L.O_IB]) + 0.0,
            current_set=float(o[L.O_ISET]),
            lost_full_steps=int(lost_full_steps(position, hs * s[L.S_QM],
                                                self.params.rotor_teeth)))

    def held_command(self):
        """
        Return the held drive command as a command row (mode, position, velocity, effort).

        The row is what :meth:`run`'s ``commands`` take: the ``drive_modes.MODE_*``
        code, the target angle [rad], the rate [rad/s] and the torque [N m],
        theta sense, as the command rules converted them.
        """
        s, hs = self.state, self.params.hand_sign
        return (s[L.S_CMODE], hs * s[L.S_CQ], hs * s[L.S_CW], hs * s[L.S_CT])

    def held_torque(self):
        """Return the held command's torque [N m], theta sense (+0.0 for a zero)."""
        return self.state[L.S_CT] * self.params.hand_sign + 0.0

    def switches(self):
        """Return the limit and home switch states of the last step (min, max, home): 0.0, 1.0."""
        s = self.state
        return (s[L.S_SWMIN], s[L.S_SWMAX], s[L.S_HOME])

    def reference_gap(self):
        """
        Return the held position target less the drive's active reference [rad], theta sense.

        Non-zero while the reference approaches a target further than
        ``max_command_jump`` (it moves at the drive's limits); 0 outside
        position mode.
        """
        s = self.state
        if int(s[L.S_DMODE]) != DM.MODE_POSITION:
            return 0.0
        return float(self.params.hand_sign * (s[L.S_CQ] - s[L.S_DQREF])) + 0.0

    def drive_fault(self):
        """Return the latched drive fault's ``drive_modes.FAULT_*`` code (``FAULT_NONE``: none)."""
        return int(self.state[L.S_DFAULT])

    def nut_to_motor(self, x):
        """
        Return the motor angle [rad] (theta sense) that puts the nut at x by the rigid kinematics.

        theta0 + h (x - x0) 2 pi / l, referenced at the initial state (as after
        homing): x0 = ``initial_position`` maps to the initial motor angle theta0.

        Parameters
        ----------
        x : float or numpy.ndarray
            Nut position [m].

        """
        P = self._P
        return self.params.hand_sign * (P[L.P_DQ0] + (np.asarray(x) - P[L.P_DX0]) / P[L.P_RT])

    def motor_to_nut(self, theta):
        """
        Return the nut position [m] of a motor angle by the rigid kinematics (see nut_to_motor).

        Parameters
        ----------
        theta : float or numpy.ndarray
            Motor angle [rad], theta sense.

        """
        P = self._P
        return P[L.P_DX0] + (self.params.hand_sign * np.asarray(theta) - P[L.P_DQ0]) * P[L.P_RT]

    def _feedback_angle(self):
        """Return the drive's position feedback now [rad], q sense (as the kernel reads it)."""
        P, s = self._P, self.state
        if P[L.P_DSCALE] > 0.5:
            return P[L.P_DQ0] + (s[L.S_XS] - P[L.P_DX0]) * (1.0 / P[L.P_RT])
        return s[L.S_EQ]


def drive_period(params, dt, nsub=None):
    """
    Return the servo drive's update period [s] for steps of dt: a whole number of substeps.

    Parameters
    ----------
    params : ScrewParams
        The axis (its drive_rate).
    dt : float
        Step [s].
    nsub : int, optional
        Substeps per step; default the model's for params and dt.

    """
    if nsub is None:
        nsub = max(1, math.ceil(dt / auto_substep(params) - 1e-9))
    m = D.update_period(nsub, dt, params.drive_rate)
    return m * dt / nsub
