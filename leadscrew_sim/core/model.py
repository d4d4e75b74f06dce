"""
LeadScrewModel: parameters + state + the fixed-step kernel (ROS-free).

Sign convention (doc/model.md section 3): theta follows the right-hand rule
about +x; the motor torque and screw angle are reported in that sense. A
positive torque moves the nut toward -x for a right-hand thread and toward +x
for a left-hand one. The parameter vector and the substep come from
:mod:`.engine.packing`, the values a step or a run reports from :mod:`.output`;
the drive commands and status are the mix-in of :mod:`.drive_control`, the
per-tick values that of :mod:`.views`.

The motor is driven in torque mode (:meth:`LeadScrewModel.advance`, :meth:`~LeadScrewModel.run`
with torques) or through the servo drive (:mod:`.engine.drive`): :meth:`~LeadScrewModel.command`
sets a held command (torque, velocity, position, quick stop) that
:meth:`~LeadScrewModel.advance_held` follows, or :meth:`~LeadScrewModel.run` takes one
command per step. With ``drive_type`` stepper the motor is a stepper behind its driver
(:mod:`.engine.stepper`): it takes position and velocity commands, refuses torques, and
:meth:`~LeadScrewModel.stepper_status` reports it.
"""
import math

import numpy as np

from . import ageing as AG
from .drive_control import DriveControl
from .engine import drive as D
from .engine import kernel as K
from .engine import layout as L
from .engine import sensors as SN
from .faults import SimulationFault
from .views import ReportedValues
from .output import (energy_balance, lost_full_steps, REPORTED, selected_result, series_result,
                     step_output, stored_energy)
from .engine.packing import auto_substep, initial_seating, MAX_SUBSTEPS_PER_STEP, pack_params
from .params import ParameterError, ScrewParams

_NO_COMMANDS = np.zeros((0, L.N_CMD))   # run_series without command rows: torque mode


class LeadScrewModel(DriveControl, ReportedValues):
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
    ageing : dict, optional
        The ageing state to start from (:meth:`ageing_state`); default a new axis.

    Raises
    ------
    ParameterError
        If the stiffest mode needs more than ``MAX_SUBSTEPS_PER_STEP`` substeps.

    """

    def __init__(self, params=None, dt=1e-3, ageing=None):
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
        self.state[L.S_LUB] = 1.0
        self.state[L.S_TEMP] = self.params.ambient_temperature
        if ageing is not None:
            aged = AG.check_state(ageing)
            for name, i in self._AGEING_SLOTS.items():
                self.state[i] = aged[name]
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
        self._report_ageing()       # the coefficients and growth the new set reports

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
        """
        Restore the initial state (static seating on the loaded flank; drive in torque mode).

        The ageing state (wear, lubricant, screw temperature:
        :meth:`ageing_state`) is the axis's history and is kept; a new axis
        is :meth:`reset_ageing`.
        """
        p = self.params
        s = self.state
        aged = s[L.S_WLA:L.S_WLA + L.N_AGEING].copy()
        s[:] = 0.0
        s[L.S_WLA:L.S_WLA + L.N_AGEING] = aged
        self._wk[:] = 0.0          # the kernel's scratch as new: a reset model is a new model
        self._iwk[:] = 0
        self._P = pack_params(p)
        q0, xa, xb = initial_seating(p, self._P, (s[L.S_WLA], s[L.S_WUA]))
        s[L.S_Q] = s[L.S_QM] = q0
        s[L.S_XA] = xa
        s[L.S_XB] = xb
        s[L.S_SWMIN] = 1.0 if xa <= p.limit_min_position else 0.0
        s[L.S_SWMAX] = 1.0 if xa >= p.limit_max_position else 0.0
        s[L.S_HOME] = 1.0 if xa >= p.home_position else 0.0
        self.fault = None
        self.out[:] = 0.0
        if p.drive_type == 'stepper':   # powered up at microstep 0, at the run current
            s[L.S_SPOS] = q0
            s[L.S_IA] = p.run_current
        td = D.update_period(self.nsub, self.dt, p.drive_rate) * (self.dt / self.nsub)
        SN.sample(self._P, s, q0, 0.0, xa, 0.0, td, 1.0, True)   # the readings at rest
        self._report_at_rest()
        self._report_ageing()
        self._e0 = self._stored_energy()
        return self

    # Ageing -----------------------------------------------------------------
    _AGEING_SLOTS = dict(zip(AG.STATE_FIELDS, range(L.S_WLA, L.S_WLA + L.N_AGEING)))

    def ageing_state(self):
        """Return the ageing state (:data:`.ageing.STATE_FIELDS`: m, -, degC) as a dict."""
        return {name: float(self.state[i]) for name, i in self._AGEING_SLOTS.items()}

    def set_ageing_state(self, values):
        """
        Replace the ageing state.

        Validated before anything changes (ParameterError names the field).
        The flanks take their new wear at the next step; :meth:`reset`
        seats the nut on them.

        Parameters
        ----------
        values : mapping
            Every field of :data:`.ageing.STATE_FIELDS` (m, -, degC).

        """
        state = AG.check_state(values)
        for name, i in self._AGEING_SLOTS.items():
            self.state[i] = state[name]
        self._report_ageing()

    def reset_ageing(self):
        """Make the axis new: no wear, fresh lubricant, the screw at the ambient temperature."""
        self.set_ageing_state(AG.fresh_state(self.params))

    def relubricate(self):
        """Renew the lubricant (L = 1); wear and temperature stay."""
        self.state[L.S_LUB] = 1.0
        self._report_ageing()

    def _report_ageing(self):
        """Fill the ageing outputs O_WLA .. O_GROW of the state now (as the kernel)."""
        o = self.out
        K.report_ageing(self._P, self.state, o, self.dt)

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
        self._refuse_torque()
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

    def run(self, torques, external_forces=None, *, commands=None, drive_values=False,
            values=None):
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
        drive_values : bool
            Also return the drive's values (as with ``commands``) of a torque run.
        values : iterable of str, optional
            Return only these arrays (names of :data:`.output.REPORTED`, the
            values a step records, in their units and senses): the lean path
            for many short runs, with no derived value (energy, nut forces,
            lost steps).

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
            before the motor lag) [N m] and velocity_reference [rad/s]. A
            stepper's runs also have step_position [rad], step_rate [rad/s],
            phase_current_a, phase_current_b, current_set [A]
            (:data:`.output.STEPPER_VALUES`) and lost_full_steps (int, a
            multiple of 4: :func:`.output.lost_full_steps`).

        Raises
        ------
        ValueError
            If an input is not finite or the lengths differ, or a stepper is given
            torques (before anything runs).
        SimulationFault
            If the state became non-finite.

        """
        hs = self.params.hand_sign
        if values is not None:
            values = tuple(values)
            unknown = [v for v in values if v not in REPORTED]
            if unknown:
                raise ValueError(f'values: {", ".join(map(repr, unknown))} not reported; '
                                 f'the allowed names are {", ".join(REPORTED)}')
        tq_q, fe, cmds = self._series_inputs(torques, external_forces, commands)
        n = len(fe)
        self._check_fault()
        rec = np.empty((n, L.REC_STATE + L.NO))
        done = K.run_series(self._P, self.state, self.out, tq_q, fe, cmds,
                            self.dt, self.nsub, self._wk, self._iwk, rec)
        if values is not None:
            res = selected_result(rec[:done], hs, values)
            if done < n:
                self._fail(f'non-finite state at step {done}; integration stopped')
            return res
        stepper = self.is_stepper
        res = series_result(rec[:done], hs, commands is not None or drive_values,
                            float(self._P[L.P_CL]), float(self._P[L.P_SL]), stepper)
        if stepper:
            res['lost_full_steps'] = lost_full_steps(res['step_position'], res['motor_angle'],
                                                     self.params.rotor_teeth)
        stored = stored_energy(self.params, self._P, rec[:done].T,
                               rec[:done, L.REC_STATE + L.O_JAM],
                               rec[:done, L.REC_STATE + L.O_WLA:L.REC_STATE + L.O_WLA + 4].T)
        res.update({name: e - e0 for name, e, e0 in
                    zip(('kinetic', 'potential', 'spring'), stored, self._e0)})
        if done < n:
            self._fail(f'non-finite state at step {done}; integration stopped')
        return res

    def _series_inputs(self, torques, external_forces, commands):
        """Return :meth:`run`'s validated inputs: torques (q sense), forces, command rows."""
        hs = self.params.hand_sign
        if commands is None:
            self._refuse_torque()
            tq = np.ascontiguousarray(torques, dtype=float)
            fe = (np.zeros_like(tq) if external_forces is None
                  else np.ascontiguousarray(external_forces, dtype=float))
            if tq.shape != fe.shape or not (np.isfinite(tq).all() and np.isfinite(fe).all()):
                raise ValueError('torques and external_forces must be finite and of equal '
                                 'length')
            return (tq if hs == 1 else -tq), fe, _NO_COMMANDS
        if torques is not None:
            raise ValueError('give torques or commands, not both (a torque mode command '
                             'row carries its torque as effort)')
        cmds = D.command_rows(commands, hs)   # validated, q sense
        if self.is_stepper:
            self._refuse_torque(cmds)
        fe = (np.zeros(len(cmds)) if external_forces is None
              else np.ascontiguousarray(external_forces, dtype=float))
        if fe.shape != (len(cmds),) or not np.isfinite(fe).all():
            raise ValueError('external_forces must be finite and as long as commands')
        return fe, fe, cmds                   # the torques are unused with command rows

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
        if P[L.P_STEPPER] > 0.5:
            o[L.O_IA] = o[L.O_ISET] = s[L.S_IA]
            o[L.O_SCMD] = s[L.S_SPOS]

    def _check_fault(self):
        """Raise the latched SimulationFault again, if any (until reset())."""
        if self.fault:
            raise SimulationFault(self.fault, self.state[L.S_T])

    def _fail(self, message):
        """Latch a fault and raise it: the one place a SimulationFault is created."""
        self.fault = message
        self._check_fault()

    @property
    def is_stepper(self):
        """Return True if the motor is a stepper with its driver (``drive_type`` stepper)."""
        return self.params.drive_type == 'stepper'

    def _refuse_torque(self, rows=None):
        """
        Raise ValueError if the axis is a stepper and a torque is commanded.

        ``rows``: command rows (q sense); a torque-mode row is refused unless its
        torque is 0 (the hold a stepper keeps after reset). None: a torque input.
        """
        if not self.is_stepper:
            return
        if rows is not None:
            bad = np.flatnonzero((rows[:, 0] == D.MODE_TORQUE) & (rows[:, 3] != 0.0))
            if not len(bad):
                return
            what = f'command {bad[0]} is a torque command'
        else:
            what = 'torque inputs'
        raise ValueError(f'{what}: a stepper drive (drive_type stepper) takes position and '
                         'velocity commands only; torque commands are refused')

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
        return stored_energy(self.params, self._P, self.state,
                             wear=self.state[L.S_WLA:L.S_WLA + 4])

    def energy(self):
        """Energy bookkeeping since reset [J], with the balance residual."""
        return energy_balance(self._stored_energy(), self._e0, self.state)
