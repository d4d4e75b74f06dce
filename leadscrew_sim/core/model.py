"""
LeadScrewModel: parameters + state + the fixed-step kernel (ROS-free).

Sign convention (physics.md section 3): theta follows the right-hand rule
about +x; the motor torque and screw angle are reported in that sense. A
positive torque moves the nut toward -x for a right-hand thread and toward +x
for a left-hand one.
"""
import dataclasses
import math

import numpy as np

from . import friction as F
from . import kernel as K
from . import layout as L
from .faults import SimulationFault
from .params import ParameterError, ScrewParams

#: Largest number of substeps one step may take before the set is refused.
MAX_SUBSTEPS_PER_STEP = 200000

CONTACT_NAMES = {1: 'leading', -1: 'trailing', 0: 'backlash'}


@dataclasses.dataclass(frozen=True)
class StepOutput:
    """Everything one step reports (SI; angles and torques in the theta sense)."""

    time: float                 #: simulated time [s]
    motor_angle: float          #: motor rotor angle [rad]
    motor_velocity: float       #: [rad/s]
    screw_angle: float          #: theta [rad]
    screw_velocity: float       #: [rad/s]
    nut_position: float         #: x of nut A [m]
    nut_velocity: float         #: [m/s]
    nut_b_position: float       #: x of half-nut B [m] (= x when no anti-backlash nut)
    motor_torque: float         #: applied (saturated, lagged) motor torque [N m]; 0 is +0.0
    normal_leading: float       #: leading flank normal force of nut A [N]
    normal_trailing: float      #: trailing flank normal force of nut A [N]
    friction_force: float       #: thread friction along the flank on nut A [N]
    sliding_velocity: float     #: v_s of nut A [m/s]
    contact: int                #: 1 leading, -1 trailing, 0 in backlash
    stuck: bool                 #: thread of nut A sticking (true stiction)
    axial_force: float          #: axial thread force of the screw on the nut(s) [N]
    thread_torque: float        #: thread reaction torque on the screw [N m]
    substeps: int               #: substeps taken in this step

    @property
    def contact_name(self):
        """'leading', 'trailing' or 'backlash'."""
        return CONTACT_NAMES[self.contact]


def pack_params(p):
    """Flatten ScrewParams into the kernel's parameter vector."""
    lam = p.lead_angle
    v = np.zeros(L.NP)
    v[L.P_RT] = p.r_m * math.tan(lam)
    v[L.P_RC] = p.r_m * math.cos(lam)
    v[L.P_SL] = math.sin(lam)
    v[L.P_CL] = math.cos(lam)
    v[L.P_B] = p.backlash
    v[L.P_K] = p.contact_stiffness
    v[L.P_C] = p.contact_damping
    v[L.P_JM] = p.motor_inertia
    v[L.P_JS] = p.screw_inertia
    v[L.P_KC] = p.coupling_stiffness
    v[L.P_CC] = p.coupling_damping
    v[L.P_RIGID] = 1.0 if p.coupling_stiffness == 0.0 else 0.0
    v[L.P_CS] = p.bearing_viscous
    v[L.P_TS0] = p.bearing_coulomb
    v[L.P_MUC] = p.collar_mu
    v[L.P_RCOL] = p.collar_radius
    v[L.P_MA] = p.nut_mass + p.payload_mass
    v[L.P_MB] = p.second_nut_mass
    v[L.P_CX] = p.guide_viscous
    v[L.P_FX0] = p.guide_coulomb
    v[L.P_GS] = p.gravity * math.sin(p.inclination)
    v[L.P_KES] = p.end_stop_stiffness
    v[L.P_CES] = p.end_stop_damping
    v[L.P_XMIN] = p.stroke_min
    v[L.P_XMAX] = p.stroke_max
    v[L.P_TMAX] = p.max_torque
    v[L.P_TAU] = p.torque_lag
    v[L.P_AB] = 1.0 if p.anti_backlash else 0.0
    v[L.P_FP] = p.preload_force
    v[L.P_KP] = p.preload_stiffness
    v[L.P_FEXT] = p.external_force
    F.pack_friction(p, v)
    return v


def _mass_matrices(p):
    """Diagonal inertia and the linearised stiffness and damping matrices."""
    rigid = p.coupling_stiffness == 0.0
    rt = p.r_m * math.tan(p.lead_angle)
    m = np.array([p.motor_inertia, p.screw_inertia, p.nut_mass + p.payload_mass,
                  p.second_nut_mass])
    kmat = np.zeros((4, 4))
    cmat = np.zeros((4, 4))

    def add(g, kk, cc):
        g = np.asarray(g, float)
        kmat[:] += kk * np.outer(g, g)
        cmat[:] += cc * np.outer(g, g)

    add([1, -1, 0, 0], p.coupling_stiffness, p.coupling_damping)
    add([0, -rt, 1, 0], p.contact_stiffness, p.contact_damping)
    add([0, 0, 1, 0], p.end_stop_stiffness, p.end_stop_damping + p.guide_viscous)
    add([0, 1, 0, 0], 0.0, p.bearing_viscous)
    keep = [0, 1, 2]
    if p.anti_backlash:
        add([0, -rt, 0, 1], p.contact_stiffness, p.contact_damping)
        add([0, 0, -1, 1], p.preload_stiffness, 0.0)
        keep.append(3)
    if rigid:
        m[1] += m[0]
        keep.remove(0)
    idx = np.array(keep)
    return m[idx], kmat[np.ix_(idx, idx)], cmat[np.ix_(idx, idx)]


def stiffest_mode(p):
    """(omega_max [rad/s], damping rate [1/s]) of the linearised chain."""
    m, kmat, cmat = _mass_matrices(p)
    s = 1.0 / np.sqrt(m)
    w2 = np.linalg.eigvalsh(kmat * np.outer(s, s)).max()
    rate = np.linalg.eigvalsh(cmat * np.outer(s, s)).max()
    return math.sqrt(max(w2, 0.0)), max(rate, 0.0)


def auto_substep(p):
    """Largest stable substep [s]: 0.2 / omega_max, and 0.2 / damping rate."""
    omega, rate = stiffest_mode(p)
    h = min(0.2 / omega if omega > 0 else math.inf, 0.2 / rate if rate > 0 else math.inf)
    if p.substep > 0.0:
        h = min(h, p.substep)
    return h if math.isfinite(h) else 1e-3


class LeadScrewModel:
    """
    A lead screw axis: validated parameters, a state vector and step().

    The state is a plain float64 array (layout in :mod:`leadscrew_sim.core.layout`);
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
        self.state = np.zeros(L.NS)
        self.out = np.zeros(L.NO)
        self._wk, self._iwk = K.workspace()
        self.fault = None
        self.reset()

    def set_params(self, params):
        """
        Swap in new parameters at run time, keeping the state.

        Geometry and the anti-backlash flag change the meaning of the state;
        callers should treat them as read-only.

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
        self.params, self._P, self.substep = params, pack_params(params), new_h
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
        """Restore the initial state (static seating on the loaded flank)."""
        p = self.params
        s = self.state
        s[:] = 0.0
        rt = self._P[L.P_RT]
        hb = 0.5 * p.backlash
        x0 = p.initial_position
        if p.anti_backlash:
            delta_a = -hb
        else:
            f0 = p.external_force - (p.nut_mass + p.payload_mass) * self._P[L.P_GS]
            delta_a = 0.0 if f0 == 0.0 else (
                (-hb + f0 / p.contact_stiffness) if f0 < 0 else (hb + f0 / p.contact_stiffness))
        q0 = (x0 - delta_a) / rt
        s[L.S_Q] = s[L.S_QM] = q0
        s[L.S_XA] = x0
        s[L.S_XB] = x0 + p.backlash if p.anti_backlash else x0
        self.fault = None
        self.out[:] = 0.0
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

    def run(self, torques, external_forces=None):
        """
        Run one step of ``dt`` per torque in a single compiled call.

        Parameters
        ----------
        torques : array_like of float
            Motor torque command of each step [N m], theta sense.
        external_forces : array_like of float, optional
            Axial force on the nut along +x of each step [N]; default zeros.

        Returns
        -------
        dict of numpy.ndarray
            time, screw_angle, screw_velocity, motor_angle, motor_velocity,
            nut_position, nut_velocity, motor_torque, axial_force,
            thread_torque, friction_force, normal_leading, normal_trailing,
            sliding_velocity, contact, stuck: one entry per step, in the units
            and senses of StepOutput.

        Raises
        ------
        ValueError
            If an input is not finite or the lengths differ (before anything runs).
        SimulationFault
            If the state became non-finite.

        """
        tq = np.ascontiguousarray(torques, dtype=float)
        fe = (np.zeros_like(tq) if external_forces is None
              else np.ascontiguousarray(external_forces, dtype=float))
        if tq.shape != fe.shape or not (np.isfinite(tq).all() and np.isfinite(fe).all()):
            raise ValueError('torques and external_forces must be finite and of equal length')
        self._check_fault()
        rec = np.empty((len(tq), L.REC_STATE + L.NO))
        hs = self.params.hand_sign
        done = K.run_series(self._P, self.state, self.out, tq if hs == 1 else -tq, fe,
                            self.dt, self.nsub, self._wk, self._iwk, rec)
        r = rec[:done]

        def hand(col):   # a q-sense column in the physical sense (a view for right hand)
            return r[:, col] if hs == 1 else -r[:, col]
        o = L.REC_STATE
        res = dict(
            time=r[:, L.S_T], screw_angle=hand(L.S_Q), screw_velocity=hand(L.S_DQ),
            motor_angle=hand(L.S_QM), motor_velocity=hand(L.S_WM),
            nut_position=r[:, L.S_XA], nut_velocity=r[:, L.S_VA],
            motor_torque=hand(o + L.O_TE) + 0.0, axial_force=r[:, o + L.O_FAX],
            thread_torque=hand(o + L.O_TTH), friction_force=r[:, o + L.O_FFA],
            normal_leading=r[:, o + L.O_NLA], normal_trailing=r[:, o + L.O_NUA],
            sliding_velocity=r[:, o + L.O_VSA], contact=r[:, o + L.O_CONTA].astype(int),
            stuck=r[:, o + L.O_STICKA] == 1.0)
        if done < len(tq):
            self._fail(f'non-finite state at step {done}; integration stopped')
        return res

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

    def joint_values(self):
        """
        Return the published values as a tuple of floats (the node's per-tick fast path).

        (screw_angle [rad], nut_position [m], screw_velocity [rad/s],
        nut_velocity [m/s], motor_torque [N m], axial_force [N], thread_torque
        [N m]): the same values as the fields of :meth:`output`.
        """
        s, o, hs = self.state.tolist(), self.out.tolist(), self.params.hand_sign
        return (hs * s[L.S_Q], s[L.S_XA], hs * s[L.S_DQ], s[L.S_VA], hs * o[L.O_TE] + 0.0,
                o[L.O_FAX], hs * o[L.O_TTH])

    def output(self):
        """Return the StepOutput of the current state and last step."""
        s, o, hs = self.state, self.out, self.params.hand_sign
        return StepOutput(
            time=s[L.S_T], motor_angle=hs * s[L.S_QM], motor_velocity=hs * s[L.S_WM],
            screw_angle=hs * s[L.S_Q], screw_velocity=hs * s[L.S_DQ],
            nut_position=s[L.S_XA], nut_velocity=s[L.S_VA], nut_b_position=s[L.S_XB],
            motor_torque=hs * o[L.O_TE] + 0.0, normal_leading=o[L.O_NLA],
            normal_trailing=o[L.O_NUA], friction_force=o[L.O_FFA],
            sliding_velocity=o[L.O_VSA], contact=int(o[L.O_CONTA]),
            stuck=bool(o[L.O_STICKA] == 1.0), axial_force=o[L.O_FAX],
            thread_torque=hs * o[L.O_TTH], substeps=int(o[L.O_NSUB]))

    def _stored_energy(self):
        """(kinetic, potential, spring) energy of the current state [J]."""
        p, s, P = self.params, self.state, self._P
        rigid = P[L.P_RIGID] > 0.5
        ma, mb = P[L.P_MA], P[L.P_MB]
        if rigid:
            kin = 0.5 * (p.motor_inertia + p.screw_inertia) * s[L.S_DQ] ** 2
        else:
            kin = 0.5 * p.motor_inertia * s[L.S_WM] ** 2 + 0.5 * p.screw_inertia * s[L.S_DQ] ** 2
        kin += 0.5 * ma * s[L.S_VA] ** 2
        pot = P[L.P_GS] * ma * s[L.S_XA]
        rt, hb, k = P[L.P_RT], 0.5 * p.backlash, p.contact_stiffness
        spring = 0.0
        bodies = [s[L.S_XA]]
        if p.anti_backlash:
            kin += 0.5 * mb * s[L.S_VB] ** 2
            pot += P[L.P_GS] * mb * s[L.S_XB]
            bodies.append(s[L.S_XB])
            stretch = p.backlash + p.preload_force / p.preload_stiffness - (s[L.S_XB] - s[L.S_XA])
            spring += 0.5 * p.preload_stiffness * stretch ** 2
        for x in bodies:
            d = x - rt * s[L.S_Q]
            for e in (-d - hb, d - hb):
                if e > 0:
                    spring += 0.5 * k * e * e
        if not rigid:
            spring += 0.5 * p.coupling_stiffness * (s[L.S_QM] - s[L.S_Q]) ** 2
        for pen in (p.stroke_min - s[L.S_XA], s[L.S_XA] - p.stroke_max):
            if pen > 0:
                spring += 0.5 * p.end_stop_stiffness * pen * pen
        return kin, pot, spring

    def energy(self):
        """Energy bookkeeping since reset [J], with the balance residual."""
        kin, pot, spring = self._stored_energy()
        k0, p0, s0 = self._e0
        s = self.state
        terms = dict(
            input_work=s[L.S_WIN], external_work=s[L.S_WEXT],
            kinetic=kin - k0, potential=pot - p0, spring=spring - s0,
            friction_dissipation=s[L.S_EFRIC], damping_dissipation=s[L.S_EDAMP])
        terms['residual'] = (terms['input_work'] + terms['external_work'] - terms['kinetic']
                             - terms['potential'] - terms['spring']
                             - terms['friction_dissipation'] - terms['damping_dissipation'])
        return terms
