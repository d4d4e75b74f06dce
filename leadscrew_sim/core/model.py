"""
LeadScrewModel: parameters + state + the fixed-step kernel (ROS-free).

Sign convention (physics.md section 3): theta follows the right-hand rule
about +x; the motor torque and screw angle are reported in that sense. A
positive torque moves the nut toward -x for a right-hand thread and toward +x
for a left-hand one. The parameter vector and the substep come from
:mod:`.packing`, the values a step or a run reports from :mod:`.output`.

The motor is driven in torque mode (:meth:`LeadScrewModel.advance`, :meth:`~LeadScrewModel.run`
with torques) or through the servo drive (:mod:`.engine.drive`): :meth:`~LeadScrewModel.command`
sets a held command (torque, velocity, position, quick stop) that
:meth:`~LeadScrewModel.advance_held` follows, or :meth:`~LeadScrewModel.run` takes one
command per step.
"""
import math

import numpy as np

from . import drive_modes as DM
from .engine import drive as D
from .engine import kernel as K
from .engine import layout as L
from .engine import sensors as SN
from .faults import SimulationFault
from .views import ReportedValues
from .output import energy_balance, series_result, step_output, stored_energy
from .engine.packing import auto_substep, initial_seating, MAX_SUBSTEPS_PER_STEP, pack_params
from .params import ParameterError, ScrewParams

_NO_COMMANDS = np.zeros((0, L.N_CMD))   # run_series without command rows: torque mode


class LeadScrewModel(ReportedValues):
    """
    A lead screw axis: validated parameters, a state vector and step().

    The state is a plain float64 array (layout in :mod:`leadscrew_sim.core.engine.layout`);
    ``step`` advances it by exactly ``dt`` in equal substeps.

    Parameters
    ----------
    params : ScrewParams, optional
        Physical parameters (default: ``ScrewParams()``, the field defaults).
    dt : float
        Fixed step [s]; the model integrates it in ``nsub`` equal substeps.

    Raises
    ------
    ParameterError
        If the stiffest mode needs more than ``MAX_SUBSTEPS_PER_STEP`` substeps.

    """

    def __init__(self, params=None, dt=1e-3):
        """Create the model at its initial state for a fixed step dt [s]."""
        self.params = params if params is not None else ScrewParams()
        self._P = pack_params(self.params)
        self.dt = float(dt)
        self.substep = auto_substep(self.params)
        self.nsub = self.substeps_for(self.dt)
        self.state = np.zeros(L.N_STATE)
        self.out = np.zeros(L.NO)
        self._wk, self._iwk = K.workspace()
        self.fault = None
        self.reset()

    def set_params(self, params):
        """
        Swap in new parameters at run time, keeping the state.

        Geometry and the anti-backlash flag change the meaning of the state;
        callers should treat them as read-only. The drive's position reference
        (:meth:`nut_to_motor`) stays that of the last reset.

        Parameters
        ----------
        params : ScrewParams
            The new physical parameters.

        Raises
        ------
        ParameterError
            If the new set needs more substeps than allowed (nothing changes).

        """
        new_h = auto_substep(params)
        old = (self.params, self._P, self.substep, self.nsub)
        new_P = pack_params(params)
        new_P[[L.P_DQ0, L.P_DX0]] = self._P[[L.P_DQ0, L.P_DX0]]   # the scale's reference stays
        self.params, self._P, self.substep = params, new_P, new_h
        try:
            self.nsub = self.substeps_for(self.dt)
        except ParameterError:
            self.params, self._P, self.substep, self.nsub = old
            raise

    def substeps_for(self, dt):
        """
        Return the number of equal substeps for a step of ``dt``.

        Parameters
        ----------
        dt : float
            Step [s], positive and finite.

        """
        if not (dt > 0.0 and math.isfinite(dt)):
            raise ParameterError('dt', f'{dt!r} s must be a positive finite step')
        n = max(1, math.ceil(dt / self.substep - 1e-9))
        if n > MAX_SUBSTEPS_PER_STEP:
            raise ParameterError('contact_stiffness', f'the stiffest mode needs a substep of '
                                 f'{self.substep:.3g} s, i.e. {n} substeps per {dt} s step '
                                 f'(limit {MAX_SUBSTEPS_PER_STEP}); soften the contact or '
                                 'raise the masses')
        return n

    def reset(self):
        """Restore the initial state (static seating on the loaded flank; drive in torque mode)."""
        p = self.params
        s = self.state
        s[:] = 0.0
        self._P = pack_params(p)
        q0, xa, xb = initial_seating(p, self._P)
        s[L.S_Q] = s[L.S_QM] = q0
        s[L.S_XA] = xa
        s[L.S_XB] = xb
        s[L.S_SWMIN] = 1.0 if xa <= p.limit_min_position else 0.0
        s[L.S_SWMAX] = 1.0 if xa >= p.limit_max_position else 0.0
        s[L.S_HOME] = 1.0 if xa >= p.home_position else 0.0
        self.fault = None
        self.out[:] = 0.0
        td = D.update_period(self.nsub, self.dt, p.drive_rate) * (self.dt / self.nsub)
        SN.sample(self._P, s, q0, 0.0, xa, 0.0, td, 1.0, True)   # the readings at rest
        self._report_at_rest()
        self._e0 = self._stored_energy()
        return self

    # Stepping ---------------------------------------------------------------
    def step(self, torque, dt=None, external_force=0.0):
        """
        Advance by one step under a motor torque and return its StepOutput.

        Parameters
        ----------
        torque : float
            Motor torque command [N m], theta sense (saturated at ``max_torque``).
        dt : float, optional
            Step [s]; default the model's ``dt``.
        external_force : float
            Axial force on the nut along +x [N], in addition to the parameter.

        Raises
        ------
        ValueError
            If an input is not finite (it never reaches the integrator).
        SimulationFault
            If the state became non-finite (the state is the one before the step).

        """
        self.advance(torque, dt, external_force)
        return self.output()

    def advance(self, torque, dt=None, external_force=0.0):
        """
        Advance by one step, like :meth:`step`, but return nothing (the fast path).

        Parameters
        ----------
        torque : float
            Motor torque command [N m], theta sense.
        dt : float, optional
            Step [s]; default the model's ``dt``.
        external_force : float
            Axial force on the nut along +x [N].

        """
        if not (math.isfinite(torque) and math.isfinite(external_force)):
            raise ValueError(f'non-finite input: torque={torque!r} N m, '
                             f'external_force={external_force!r} N')
        self._check_fault()
        if dt is None or dt == self.dt:
            dt, n = self.dt, self.nsub
        else:
            n = self.substeps_for(dt)
        rc = K.step(self._P, self.state, self.out, self._P_hand() * torque,
                    float(external_force), float(dt), n, self._wk, self._iwk)
        if rc != 0:   # the kernel left the state as it was before this step
            self._fail(f'non-finite state at t={self.state[L.S_T]:.6f} s '
                       f'(torque {torque} N m); integration stopped')

    def run(self, torques, external_forces=None, *, commands=None):
        """
        Run one step of ``dt`` per torque (or per drive command) in a single compiled call.

        Parameters
        ----------
        torques : array_like of float or None
            Motor torque command of each step [N m], theta sense (torque mode).
            None when ``commands`` is given.
        external_forces : array_like of float, optional
            Axial force on the nut along +x of each step [N]; default zeros.
        commands : array_like of float, shape (n, 4), optional
            One drive command per step, theta sense: (mode, position [rad],
            velocity [rad/s], effort [N m]) as :meth:`command` takes them (mode
            a ``drive_modes.MODE_*`` code); NaN in position, velocity or effort means
            not commanded (an unused field, or a zero feed-forward). The last
            row stays the held command.

        Returns
        -------
        dict of numpy.ndarray
            time, screw_angle, screw_velocity, motor_angle, motor_velocity,
            nut_position, nut_velocity, motor_torque, axial_force,
            thread_torque, friction_force, normal_leading, normal_trailing,
            sliding_velocity, contact, stuck: one entry per step, in the units
            and senses of StepOutput; nut_b_position [m], nut_b_velocity [m/s],
            nut_force and nut_b_force (the axial thread force on each nut body
            [N]) as :meth:`truth_values`; sensor_screw_angle [rad],
            sensor_screw_velocity [rad/s], sensor_nut_position [m] and
            sensor_nut_velocity [m/s], what the sensors report
            (:meth:`joint_values`); the same of half-nut B as contact_b,
            stuck_b, normal_leading_b, normal_trailing_b, friction_force_b,
            sliding_velocity_b; stick_a, stick_b (1 stuck, 0 sliding, -1 no
            load); the energy terms since reset [J] of :meth:`energy` but the
            residual (input_work, external_work, kinetic, potential, spring,
            friction_dissipation, damping_dissipation). With ``commands`` also the drive's: mode,
            fault (codes), limit_min, limit_max, home (bool),
            following_error [rad], drive_torque (the drive's torque command
            before the motor lag) [N m] and velocity_reference [rad/s].

        Raises
        ------
        ValueError
            If an input is not finite or the lengths differ (before anything runs).
        SimulationFault
            If the state became non-finite.

        """
        hs = self.params.hand_sign
        if commands is None:
            tq = np.ascontiguousarray(torques, dtype=float)
            fe = (np.zeros_like(tq) if external_forces is None
                  else np.ascontiguousarray(external_forces, dtype=float))
            if tq.shape != fe.shape or not (np.isfinite(tq).all() and np.isfinite(fe).all()):
                raise ValueError('torques and external_forces must be finite and of equal '
                                 'length')
            cmds, tq_q = _NO_COMMANDS, (tq if hs == 1 else -tq)
        else:
            if torques is not None:
                raise ValueError('give torques or commands, not both (a torque mode command '
                                 'row carries its torque as effort)')
            cmds = D.command_rows(commands, self.params.hand_sign)   # validated, q sense
            fe = (np.zeros(len(cmds)) if external_forces is None
                  else np.ascontiguousarray(external_forces, dtype=float))
            if fe.shape != (len(cmds),) or not np.isfinite(fe).all():
                raise ValueError('external_forces must be finite and as long as commands')
            tq_q = fe                             # unused with command rows: only its length
        n = len(fe)
        self._check_fault()
        rec = np.empty((n, L.REC_STATE + L.NO))
        done = K.run_series(self._P, self.state, self.out, tq_q, fe, cmds,
                            self.dt, self.nsub, self._wk, self._iwk, rec)
        res = series_result(rec[:done], hs, commands is not None, float(self._P[L.P_CL]),
                            float(self._P[L.P_SL]))
        stored = stored_energy(self.params, self._P, rec[:done].T,
                               rec[:done, L.REC_STATE + L.O_JAM])
        res.update({name: e - e0 for name, e, e0 in
                    zip(('kinetic', 'potential', 'spring'), stored, self._e0)})
        if done < n:
            self._fail(f'non-finite state at step {done}; integration stopped')
        return res

    # Servo drive --------------------------------------------------------------
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
            If the mode is unknown or its command is not finite (nothing changes).

        """
        code = DM.mode_code(mode)
        row = np.array([[code, float(position), float(velocity), float(effort)]])
        if D.prepare_commands(row, self.params.hand_sign) >= 0:   # the rule of a command row
            raise ValueError(f'mode {DM.MODE_NAMES[code]} needs a finite '
                             f'{("effort", "velocity", "position", "")[code]} and finite '
                             f'feed-forwards; got position={position!r}, velocity={velocity!r}, '
                             f'effort={effort!r}')
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
        a new command takes over from the next step.

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

    def drive_fault(self):
        """Return the latched drive fault's ``drive_modes.FAULT_*`` code (``FAULT_NONE``: none)."""
        return int(self.state[L.S_DFAULT])

    def place_at_rest(self, theta, motor_offset, motor_rate):
        """
        Move the axis onto a rest, in place: screw at theta, screw and nut still.

        The nut positions and the scale reading move with the screw through the
        lead (the contact gap is kept); the motor is put at theta +
        motor_offset with rate motor_rate (its encoder moves with it).

        Parameters
        ----------
        theta : float
            Screw angle [rad], theta sense.
        motor_offset : float
            Motor angle less the screw angle [rad], theta sense.
        motor_rate : float
            Motor rate [rad/s], theta sense.

        """
        s, hs = self.state, self.params.hand_sign
        ratio = self.params.lead_ratio
        q = hs * theta
        dq = q - s[L.S_Q]
        s[L.S_Q] = q
        s[L.S_DQ] = 0.0
        for x, v in ((L.S_XA, L.S_VA), (L.S_XB, L.S_VB)):
            s[x] += dq * ratio
            s[v] = 0.0
        s[L.S_XS] += dq * ratio
        s[L.S_VS] = 0.0
        qm = q + hs * motor_offset
        s[L.S_EQ] += qm - s[L.S_QM]
        s[L.S_QM] = qm
        s[L.S_WM] = hs * motor_rate
        s[L.S_EW] = s[L.S_WM]

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

    def _report_at_rest(self):
        """Fill the reported joint values O_JQ .. O_JV of the state at reset (as the kernel)."""
        P, s, o = self._P, self.state, self.out
        ideal = P[L.P_EIDEAL] > 0.5
        o[L.O_JQ] = s[L.S_Q] if ideal else s[L.S_EQ]
        o[L.O_JW] = 0.0
        if P[L.P_SFIT] <= 0.5:
            o[L.O_JX] = P[L.P_DX0] + (s[L.S_EQ] - P[L.P_DQ0]) * P[L.P_RT]
        else:
            o[L.O_JX] = s[L.S_XS]
        o[L.O_JV] = 0.0

    def _check_fault(self):
        """Raise the latched SimulationFault again, if any (until reset())."""
        if self.fault:
            raise SimulationFault(self.fault, self.state[L.S_T])

    def _fail(self, message):
        """Latch a fault and raise it: the one place a SimulationFault is created."""
        self.fault = message
        self._check_fault()

    def _P_hand(self):
        return self.params.hand_sign

    # Views ------------------------------------------------------------------
    @property
    def time(self):
        """Return the simulated time [s]."""
        return self.state[L.S_T]

    def output(self):
        """Return the StepOutput of the current state and last step."""
        return step_output(self.state, self.out, self.params.hand_sign)

    def _stored_energy(self):
        """(kinetic, potential, spring) energy of the current state [J]."""
        return stored_energy(self.params, self._P, self.state)

    def energy(self):
        """Energy bookkeeping since reset [J], with the balance residual."""
        return energy_balance(self._stored_energy(), self._e0, self.state)
