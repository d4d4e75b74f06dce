"""
What the model reports: the StepOutput of a step, the arrays of a run, the energy.

:class:`StepOutput` holds one step's values and :func:`step_output` fills it;
:func:`series_result` turns the records of a compiled run into the per-step
arrays of :meth:`~.model.LeadScrewModel.run`; :func:`stored_energy` is the
kinetic, potential and spring energy of a state, for the energy balance that
:func:`energy_balance` draws up.
Angles and torques are reported in the theta sense (physics.md section 3).
"""
import dataclasses

import numpy as np

from .engine import layout as L

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


def step_output(s, o, hs):
    """
    Return the StepOutput of a state and the outputs of its last step.

    Parameters
    ----------
    s : numpy.ndarray
        The state vector (q sense).
    o : numpy.ndarray
        The output vector of the last step (q sense).
    hs : int
        The hand sign of the thread (+1 right, -1 left).

    """
    return StepOutput(
        time=s[L.S_T], motor_angle=hs * s[L.S_QM], motor_velocity=hs * s[L.S_WM],
        screw_angle=hs * s[L.S_Q], screw_velocity=hs * s[L.S_DQ],
        nut_position=s[L.S_XA], nut_velocity=s[L.S_VA], nut_b_position=s[L.S_XB],
        motor_torque=hs * o[L.O_TE] + 0.0, normal_leading=o[L.O_NLA],
        normal_trailing=o[L.O_NUA], friction_force=o[L.O_FFA],
        sliding_velocity=o[L.O_VSA], contact=int(o[L.O_CONTA]),
        stuck=bool(o[L.O_STICKA] == 1.0), axial_force=o[L.O_FAX],
        thread_torque=hs * o[L.O_TTH], substeps=int(o[L.O_NSUB]))


def series_result(r, hs, drive, cl=1.0, sl=0.0):
    """
    Return the per-step arrays of a run from its records, in the theta sense.

    Parameters
    ----------
    r : numpy.ndarray, shape (n, REC_STATE + NO)
        The records of the steps done: state, then outputs (q sense).
    hs : int
        The hand sign of the thread (+1 right, -1 left).
    drive : bool
        Add the drive's outputs (a run with command rows).
    cl, sl : float
        cos and sin of the lead angle (the per-nut axial forces).

    """

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
        stuck=r[:, o + L.O_STICKA] == 1.0,
        nut_b_position=r[:, L.S_XB], nut_b_velocity=r[:, L.S_VB],
        sensor_screw_angle=hand(o + L.O_JQ), sensor_screw_velocity=hand(o + L.O_JW),
        sensor_nut_position=r[:, o + L.O_JX], sensor_nut_velocity=r[:, o + L.O_JV])
    res.update(
        contact_b=r[:, o + L.O_CONTB].astype(int), stuck_b=r[:, o + L.O_STICKB] == 1.0,
        normal_leading_b=r[:, o + L.O_NLB], normal_trailing_b=r[:, o + L.O_NUB],
        friction_force_b=r[:, o + L.O_FFB], sliding_velocity_b=r[:, o + L.O_VSB],
        stick_a=r[:, o + L.O_STICKA], stick_b=r[:, o + L.O_STICKB],
        input_work=r[:, L.S_WIN], external_work=r[:, L.S_WEXT],
        friction_dissipation=r[:, L.S_EFRIC], damping_dissipation=r[:, L.S_EDAMP])
    # the axial thread force on nut A, and the rest on half-nut B, as truth_values() forms them
    f_a = ((r[:, o + L.O_NLA] - r[:, o + L.O_NUA]) * cl + r[:, o + L.O_FFA] * sl)
    res.update(nut_force=f_a, nut_b_force=r[:, o + L.O_FAX] - f_a)
    if drive:   # the drive's outputs O_DMODE .. O_DWREF, in one copy
        d = np.ascontiguousarray(r[:, o + L.O_DMODE:o + L.O_DWREF + 1].T)
        d0 = L.O_DMODE
        ang = d[L.O_DFERR - d0:]        # following error, drive torque, velocity reference
        ang *= hs                       # q sense -> theta sense
        ang += 0.0                      # no -0.0
        res.update(
            mode=d[L.O_DMODE - d0].astype(int), fault=d[L.O_DFAULT - d0].astype(int),
            limit_min=d[L.O_SWMIN - d0] == 1.0, limit_max=d[L.O_SWMAX - d0] == 1.0,
            home=d[L.O_HOME - d0] == 1.0, following_error=ang[0],
            drive_torque=ang[L.O_DTCMD - L.O_DFERR],
            velocity_reference=ang[L.O_DWREF - L.O_DFERR])
    return res


def stored_energy(p, P, s, jam_side=None):
    """
    Return the (kinetic, potential, spring) energy [J] of a state, or of many.

    Parameters
    ----------
    p : ScrewParams
        Physical parameters.
    P : numpy.ndarray
        Their parameter vector.
    s : numpy.ndarray
        The state vector, or the records of a run transposed (``s[i]`` one
        column per state slot ``i`` < ``REC_STATE``): then the energies are arrays.
    jam_side : float or numpy.ndarray, optional
        The side the jam blocks (``S_JAM``); default ``s[S_JAM]``.

    """
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
            e = np.maximum(e, 0.0)
            spring += 0.5 * k * e * e
    if not rigid:
        spring += 0.5 * p.coupling_stiffness * (s[L.S_QM] - s[L.S_Q]) ** 2
    side = s[L.S_JAM] if jam_side is None else jam_side
    jam = side * (s[L.S_XA] - P[L.P_JAMX])   # the jam's penetration, if engaged
    for pen in (p.stroke_min - s[L.S_XA], s[L.S_XA] - p.stroke_max, jam):
        pen = np.maximum(pen, 0.0)
        spring += 0.5 * p.end_stop_stiffness * pen * pen
    return kin, pot, spring


def energy_balance(stored, stored0, s):
    """
    Return the energy bookkeeping since reset [J], with the balance residual.

    Parameters
    ----------
    stored : tuple of float
        (kinetic, potential, spring) energy of the state now (:func:`stored_energy`).
    stored0 : tuple of float
        The same at reset.
    s : numpy.ndarray
        The state vector (its work and dissipation accumulators).

    """
    kin, pot, spring = stored
    k0, p0, s0 = stored0
    terms = dict(
        input_work=s[L.S_WIN], external_work=s[L.S_WEXT],
        kinetic=kin - k0, potential=pot - p0, spring=spring - s0,
        friction_dissipation=s[L.S_EFRIC], damping_dissipation=s[L.S_EDAMP])
    terms['residual'] = (terms['input_work'] + terms['external_work'] - terms['kinetic']
                         - terms['potential'] - terms['spring']
                         - terms['friction_dissipation'] - terms['damping_dissipation'])
    return terms
