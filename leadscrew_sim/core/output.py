"""
What the model reports: the StepOutput of a step, the arrays of a run, the energy.

:data:`REPORTED` is the one rule of what a step reports: where each value
is read in the kernel's record row and how its q sense becomes the theta
sense; a :class:`Reading` applies it to some of the values. :class:`StepOutput`
holds one step's values and :func:`step_output` fills it;
:func:`series_result` turns the records of a compiled run into the per-step
arrays of :meth:`~.model.LeadScrewModel.run`; the model's per-tick views read
a :func:`record_row` as plain floats; :func:`nut_forces` splits the axial
thread force between the nut bodies. :func:`stored_energy` is the kinetic,
potential and spring energy of a state, for the energy balance that
:func:`energy_balance` draws up.
Angles and torques are reported in the theta sense (doc/model.md section 3).
"""
import dataclasses
import operator

import numpy as np

from .engine import layout as L

CONTACT_NAMES = {1: 'leading', -1: 'trailing', 0: 'backlash'}

#: Sense of a reported value: AS_RECORDED as the kernel holds it; THETA an angle,
#: rate or torque held in the q sense, reported times the hand sign h (theta sense);
#: THETA_NO_NEG_ZERO the same, then +0.0 added (a zero is reported as +0.0).
AS_RECORDED, THETA, THETA_NO_NEG_ZERO = 0, 1, 2

#: Kind of a reported value: FLOAT a number; CODE an integer code; FLAG true where
#: the recorded value is 1.0.
FLOAT, CODE, FLAG = 0, 1, 2

_O = L.REC_STATE   # the column of output slot 0 in a record row

#: What a step reports: name -> (column, sense, kind). The column is one of the
#: kernel's record row (layout: the state's first REC_STATE slots, then the NO
#: outputs); the order is that of the arrays of a run.
REPORTED = {
    'time': (L.S_T, AS_RECORDED, FLOAT),
    'screw_angle': (L.S_Q, THETA, FLOAT),
    'screw_velocity': (L.S_DQ, THETA, FLOAT),
    'motor_angle': (L.S_QM, THETA, FLOAT),
    'motor_velocity': (L.S_WM, THETA, FLOAT),
    'nut_position': (L.S_XA, AS_RECORDED, FLOAT),
    'nut_velocity': (L.S_VA, AS_RECORDED, FLOAT),
    'motor_torque': (_O + L.O_TE, THETA_NO_NEG_ZERO, FLOAT),
    'axial_force': (_O + L.O_FAX, AS_RECORDED, FLOAT),
    'thread_torque': (_O + L.O_TTH, THETA, FLOAT),
    'friction_force': (_O + L.O_FFA, AS_RECORDED, FLOAT),
    'normal_leading': (_O + L.O_NLA, AS_RECORDED, FLOAT),
    'normal_trailing': (_O + L.O_NUA, AS_RECORDED, FLOAT),
    'sliding_velocity': (_O + L.O_VSA, AS_RECORDED, FLOAT),
    'contact': (_O + L.O_CONTA, AS_RECORDED, CODE),
    'stuck': (_O + L.O_STICKA, AS_RECORDED, FLAG),
    'nut_b_position': (L.S_XB, AS_RECORDED, FLOAT),
    'nut_b_velocity': (L.S_VB, AS_RECORDED, FLOAT),
    'sensor_screw_angle': (_O + L.O_JQ, THETA, FLOAT),
    'sensor_screw_velocity': (_O + L.O_JW, THETA, FLOAT),
    'sensor_nut_position': (_O + L.O_JX, AS_RECORDED, FLOAT),
    'sensor_nut_velocity': (_O + L.O_JV, AS_RECORDED, FLOAT),
    'contact_b': (_O + L.O_CONTB, AS_RECORDED, CODE),
    'stuck_b': (_O + L.O_STICKB, AS_RECORDED, FLAG),
    'normal_leading_b': (_O + L.O_NLB, AS_RECORDED, FLOAT),
    'normal_trailing_b': (_O + L.O_NUB, AS_RECORDED, FLOAT),
    'friction_force_b': (_O + L.O_FFB, AS_RECORDED, FLOAT),
    'sliding_velocity_b': (_O + L.O_VSB, AS_RECORDED, FLOAT),
    'stick_a': (_O + L.O_STICKA, AS_RECORDED, FLOAT),
    'stick_b': (_O + L.O_STICKB, AS_RECORDED, FLOAT),
    'input_work': (L.S_WIN, AS_RECORDED, FLOAT),
    'external_work': (L.S_WEXT, AS_RECORDED, FLOAT),
    'friction_dissipation': (L.S_EFRIC, AS_RECORDED, FLOAT),
    'damping_dissipation': (L.S_EDAMP, AS_RECORDED, FLOAT),
    'substeps': (_O + L.O_NSUB, AS_RECORDED, CODE),
    'mode': (_O + L.O_DMODE, AS_RECORDED, CODE),
    'fault': (_O + L.O_DFAULT, AS_RECORDED, CODE),
    'limit_min': (_O + L.O_SWMIN, AS_RECORDED, FLAG),
    'limit_max': (_O + L.O_SWMAX, AS_RECORDED, FLAG),
    'home': (_O + L.O_HOME, AS_RECORDED, FLAG),
    'following_error': (_O + L.O_DFERR, THETA_NO_NEG_ZERO, FLOAT),
    'drive_torque': (_O + L.O_DTCMD, THETA_NO_NEG_ZERO, FLOAT),
    'velocity_reference': (_O + L.O_DWREF, THETA_NO_NEG_ZERO, FLOAT),
    'step_position': (_O + L.O_SCMD, THETA, FLOAT),
    'step_rate': (_O + L.O_SRATE, THETA_NO_NEG_ZERO, FLOAT),
    'phase_current_a': (_O + L.O_IA, AS_RECORDED, FLOAT),
    'phase_current_b': (_O + L.O_IB, THETA, FLOAT),
    'current_set': (_O + L.O_ISET, AS_RECORDED, FLOAT),
    # the ageing (doc/model.md section 19) at the step's end: m, m, m, m, m, N, -, -, -,
    # degC, W, m
    'wear_leading_a': (_O + L.O_WLA, AS_RECORDED, FLOAT),
    'wear_trailing_a': (_O + L.O_WUA, AS_RECORDED, FLOAT),
    'wear_leading_b': (_O + L.O_WLB, AS_RECORDED, FLOAT),
    'wear_trailing_b': (_O + L.O_WUB, AS_RECORDED, FLOAT),
    'backlash': (_O + L.O_BLASH, AS_RECORDED, FLOAT),
    'preload': (_O + L.O_PRELOAD, AS_RECORDED, FLOAT),
    'lubricant': (_O + L.O_LUB, AS_RECORDED, FLOAT),
    'mu_k': (_O + L.O_MUK, AS_RECORDED, FLOAT),
    'mu_s': (_O + L.O_MUS, AS_RECORDED, FLOAT),
    'screw_temperature': (_O + L.O_TEMP, AS_RECORDED, FLOAT),
    'heat_flow': (_O + L.O_HEAT, AS_RECORDED, FLOAT),
    'thermal_growth': (_O + L.O_GROW, AS_RECORDED, FLOAT),
}

#: The ageing's values (doc/model.md section 19), in every run's arrays.
AGEING_VALUES = ('wear_leading_a', 'wear_trailing_a', 'wear_leading_b', 'wear_trailing_b',
                 'backlash', 'preload', 'lubricant', 'mu_k', 'mu_s', 'screw_temperature',
                 'heat_flow', 'thermal_growth')

#: The drive's values: in the arrays of a run with command rows only.
DRIVE_VALUES = ('mode', 'fault', 'limit_min', 'limit_max', 'home', 'following_error',
                'drive_torque', 'velocity_reference')

#: The stepper's values (doc/model.md section 18): in the arrays of a stepper's runs only.
#: step_position [rad] and step_rate [rad/s]: the motor angle and rate the step
#: generator commands (the angle of the microstep the driver sets); phase_current_a,
#: phase_current_b [A] (physical phases: theta_e = N_r theta, i_a* = I cos, i_b* = I sin);
#: current_set [A]: the amplitude I set (run or hold current, 0 disabled).
STEPPER_VALUES = ('step_position', 'step_rate', 'phase_current_a', 'phase_current_b',
                  'current_set')

#: The arrays of every run, before the nut forces (:func:`nut_forces`) and the drive's.
RUN_VALUES = tuple(n for n in REPORTED if n != 'substeps' and n not in DRIVE_VALUES
                   and n not in STEPPER_VALUES)


class Reading:
    """
    How to read some of the values of :data:`REPORTED` from a record row, in their sense.

    Called with a record row (a sequence indexed by its columns: a list of
    floats, a numpy row, or the transposed records of a run for arrays) and
    the hand sign, it returns the values in the order of ``names``.

    Parameters
    ----------
    names : iterable of str
        Names of :data:`REPORTED`, at least two.

    """

    def __init__(self, names):
        """Keep the columns, the values to turn into the theta sense and the kinds."""
        self.names = tuple(names)
        spec = [REPORTED[n] for n in self.names]
        self.kinds = tuple(kind for _col, _sense, kind in spec)
        self._get = operator.itemgetter(*(col for col, _sense, _kind in spec))
        self._theta = tuple(i for i, (_c, sense, _k) in enumerate(spec) if sense != AS_RECORDED)
        self._no_neg_zero = tuple(i for i, (_c, sense, _k) in enumerate(spec)
                                  if sense == THETA_NO_NEG_ZERO)

    def __call__(self, row, hs):
        """Return the values of ``row`` (hand sign ``hs``) as a list, numbers whatever kind."""
        v = list(self._get(row))
        if hs != 1:
            for i in self._theta:
                v[i] = hs * v[i]
        for i in self._no_neg_zero:
            v[i] = v[i] + 0.0
        return v


def record_row(s, o):
    """Return the record row of a state and its outputs as a list of floats (q sense)."""
    return s[:L.REC_STATE].tolist() + o.tolist()


def nut_forces(normal_leading, normal_trailing, friction_force, axial_force, cl, sl):
    """
    Return the axial thread force on nut A and the rest, on half-nut B [N].

    Parameters
    ----------
    normal_leading, normal_trailing, friction_force : float or numpy.ndarray
        Flank normal forces and thread friction force of nut A [N].
    axial_force : float or numpy.ndarray
        Axial thread force on both nut bodies [N].
    cl, sl : float
        cos and sin of the lead angle.

    """
    f_a = (normal_leading - normal_trailing) * cl + friction_force * sl
    return f_a, axial_force - f_a


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


_STEP = Reading(f.name for f in dataclasses.fields(StepOutput))
_RUN = Reading(RUN_VALUES)
_DRIVE = Reading(DRIVE_VALUES)
_STEPPER = Reading(STEPPER_VALUES)


def step_output(s, o, hs):
    """
    Return the StepOutput of a state and the outputs of its last step.

    Parameters
    ----------
    s : numpy.ndarray
        The state vector (q sense).
    o : numpy.ndarray
        The output vector of the last step (q sense).
    hs : float
        The hand sign of the thread (+1 left, -1 right).

    """
    values = _STEP(np.concatenate((s[:L.REC_STATE], o)), hs)
    return StepOutput(*(int(v) if kind == CODE else bool(v == 1.0) if kind == FLAG else v
                        for v, kind in zip(values, _STEP.kinds)))


def _arrays(reading, r, hs):
    """Return {name: array} of a reading of the records ``r`` of a run."""
    return {name: v.astype(int) if kind == CODE else v == 1.0 if kind == FLAG else v
            for name, v, kind in zip(reading.names, reading(r.T, hs), reading.kinds)}


def series_result(r, hs, drive, cl=1.0, sl=0.0, stepper=False):
    """
    Return the per-step arrays of a run from its records, in the theta sense.

    Parameters
    ----------
    r : numpy.ndarray, shape (n, REC_STATE + NO)
        The records of the steps done: state, then outputs (q sense).
    hs : float
        The hand sign of the thread (+1 left, -1 right).
    drive : bool
        Add the drive's outputs (a run with command rows).
    cl, sl : float
        cos and sin of the lead angle (the per-nut axial forces).
    stepper : bool
        Add the stepper's outputs (:data:`STEPPER_VALUES`).

    """
    res = _arrays(_RUN, r, hs)
    res['nut_force'], res['nut_b_force'] = nut_forces(
        res['normal_leading'], res['normal_trailing'], res['friction_force'],
        res['axial_force'], cl, sl)
    res['wear_leading'] = res['wear_leading_a'] + res['wear_leading_b']
    res['wear_trailing'] = res['wear_trailing_a'] + res['wear_trailing_b']
    if drive:
        res.update(_arrays(_DRIVE, r, hs))
    if stepper:
        res.update(_arrays(_STEPPER, r, hs))
    return res


def selected_result(r, hs, names):
    """
    Return some per-step arrays of a run from its records: name -> array, theta sense.

    The lean reading of :func:`series_result`: only the :data:`REPORTED`
    values named, nothing derived (no nut forces, no energy).

    Parameters
    ----------
    r : numpy.ndarray, shape (n, REC_STATE + NO)
        The records of the steps done (q sense).
    hs : float
        The hand sign of the thread (+1 left, -1 right).
    names : iterable of str
        Names of :data:`REPORTED`.

    """
    res = {}
    for name in names:
        col, sense, kind = REPORTED[name]
        v = r[:, col]
        if sense != AS_RECORDED and hs != 1:
            v = hs * v
        if sense == THETA_NO_NEG_ZERO:
            v = v + 0.0
        res[name] = (v.astype(int) if kind == CODE else v == 1.0 if kind == FLAG
                     else np.array(v))
    return res


def lost_full_steps(step_position, motor_angle, rotor_teeth):
    """
    Return the full steps the rotor lost against the command: a multiple of 4 (simulation truth).

    4 round(N_r (theta_cmd - theta_m) / (2 pi)): the whole electrical cycles
    (4 full steps each) between the commanded angle and the rotor, whose
    stable rest lies within a quarter cycle of its equilibrium; positive when
    the rotor is behind a command in +theta. A real driver cannot know it.

    Parameters
    ----------
    step_position, motor_angle : float or numpy.ndarray
        Commanded and true motor angle [rad], theta sense.
    rotor_teeth : float
        N_r of the motor.

    """
    cycles = np.round(rotor_teeth * (np.asarray(step_position) - motor_angle) / (2.0 * np.pi))
    return 4 * cycles.astype(int)


def stored_energy(p, P, s, jam_side=None, wear=(0.0, 0.0, 0.0, 0.0)):
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
    wear : sequence of float or numpy.ndarray
        Wear depths [m] of the flanks (nut A lower, upper; half-nut B lower,
        upper): each flank's penetration counts from its worn surface, and a
        split nut's spring past its free length is the tie of
        :mod:`.engine.ageing` when the flanks wear.

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
        stiff = p.preload_stiffness
        if p.wear_rate > 0.0:   # the tie (0.5 k) past the spring's free length
            stiff = np.where(stretch < 0.0, 0.5 * k, stiff)
            stiff = stiff if np.ndim(stiff) else float(stiff)
        spring += 0.5 * stiff * stretch ** 2
    for x, w_lo, w_up in zip(bodies, wear[0::2], wear[1::2]):
        d = x - rt * s[L.S_Q]
        for e in (-d - hb - w_lo, d - hb - w_up):
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
