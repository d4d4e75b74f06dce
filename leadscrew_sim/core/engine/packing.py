"""
The parameter vector of the kernel and the substep the parameters need.

:func:`pack_params` flattens a :class:`~.params.ScrewParams` into the float64
vector the kernel reads (layout in :mod:`.layout`; the friction law's block by
:mod:`.friction`, the drive's by :func:`pack_drive`, the sensors' by
:mod:`.sensors`), with the initial seating
(:func:`initial_seating`) that references the drive's position scale.
:func:`stiffest_mode` linearises the chain and :func:`auto_substep` derives the
largest stable substep from it; :data:`MAX_SUBSTEPS_PER_STEP` bounds how many
of those one step may take.
"""
import math

import numpy as np

from ..drive_modes import OVERSPEED_MARGIN
from . import ageing as AG
from . import friction as F
from . import layout as L
from . import sensors as SN


#: Largest number of substeps one step may take before the set is refused.
MAX_SUBSTEPS_PER_STEP = 200000


def pack_params(p):
    """
    Flatten ScrewParams into the kernel's parameter vector.

    Parameters
    ----------
    p : ScrewParams
        Validated physical parameters.

    """
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
    AG.pack_ageing(p, v)
    SN.pack_sensors(p, v)
    pack_drive(p, v, initial_seating(p, v)[0])
    pack_stepper(p, v)
    return v


def pack_stepper(p, v):
    """
    Fill the stepper's slots of the parameter vector v from ScrewParams p (stepper.py).

    Every set packs them (a servo set's stepper figures are valid defaults);
    P_STEPPER says whether the kernel runs the stepper.

    Parameters
    ----------
    p : ScrewParams
        The parameters.
    v : numpy.ndarray
        The parameter vector (layout.NP floats).

    """
    v[L.P_STEPPER] = 1.0 if p.drive_type == 'stepper' else 0.0
    v[L.P_NR] = p.rotor_teeth
    v[L.P_USTEP] = p.step_angle / p.microsteps
    v[L.P_KM] = p.torque_constant
    v[L.P_IRUN] = p.run_current
    v[L.P_IHOLD] = p.hold_current
    v[L.P_THOLD] = p.hold_current_delay
    v[L.P_RPH] = p.phase_resistance
    v[L.P_LPH] = p.phase_inductance
    v[L.P_TDET] = p.detent_torque
    v[L.P_VSUP] = p.supply_voltage
    v[L.P_KI] = max(0.0, 2.0 * math.pi * p.current_loop_bandwidth * p.phase_inductance
                    - p.phase_resistance)
    v[L.P_SWMAX] = p.max_step_rate * p.step_angle
    v[L.P_SACC] = p.step_acceleration * p.step_angle
    v[L.P_BROT] = p.rotor_damping
    v[L.P_SNOENC] = 1.0 if p.encoder_counts == 0 else 0.0


def pack_drive(p, v, q0):
    """
    Fill the drive's slots of the parameter vector v from ScrewParams p.

    Parameters
    ----------
    p : ScrewParams
        The parameters.
    v : numpy.ndarray
        The parameter vector (layout.NP floats); P_RT must be set.
    q0 : float
        Motor angle of the initial state [rad], q sense: the linear scale's reference.

    """
    v[L.P_DRATE] = p.drive_rate
    v[L.P_DKP] = p.position_gain
    v[L.P_DKV] = p.velocity_gain
    v[L.P_DTI] = p.velocity_integral_time
    v[L.P_DVMAX] = p.reference_speed_limit
    v[L.P_DQSD] = p.quick_stop_deceleration
    v[L.P_DFEL] = p.following_error_limit
    v[L.P_DTLT] = p.torque_limit_time
    v[L.P_DSCALE] = 1.0 if p.drive_feedback == 'linear_scale' else 0.0
    v[L.P_DQ0] = q0
    v[L.P_DX0] = p.initial_position
    v[L.P_LMIN] = p.limit_min_position
    v[L.P_LMAX] = p.limit_max_position
    v[L.P_HOME] = p.home_position
    v[L.P_HYST] = p.switch_hysteresis
    v[L.P_OVS] = OVERSPEED_MARGIN * p.max_screw_velocity
    v[L.P_DJUMP] = p.max_command_jump / abs(v[L.P_RT])
    v[L.P_DSLEW] = v[L.P_DVMAX]


def initial_seating(p, v, wear=(0.0, 0.0)):
    """
    Return (q0 [rad], x_a [m], x_b [m]): the initial screw/motor angle (q sense) and nut positions.

    The nut rests at ``initial_position`` on the flank its static load presses
    (doc/model.md section 12, initial state); the screw angle follows from the flank
    penetration of that load, from flanks receded by their wear (a split
    nut's halves settle on their worn flanks in the first steps).

    Parameters
    ----------
    p : ScrewParams
        Validated physical parameters.
    v : numpy.ndarray
        The parameter vector of ``p`` (P_RT and P_GS used).
    wear : tuple of float
        Wear depths of nut A's lower and upper flank [m].

    """
    rt = v[L.P_RT]
    hb = 0.5 * p.backlash
    x0 = p.initial_position
    if p.anti_backlash:
        delta_a = -hb
    else:
        f0 = p.external_force - (p.nut_mass + p.payload_mass) * v[L.P_GS]
        delta_a = 0.0 if f0 == 0.0 else (
            (-hb - wear[0] + f0 / p.contact_stiffness) if f0 < 0
            else (hb + wear[1] + f0 / p.contact_stiffness))
    return (x0 - delta_a) / rt, x0, (x0 + p.backlash if p.anti_backlash else x0)


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
    """
    Return (omega_max [rad/s], damping rate [1/s]) of the linearised chain.

    Parameters
    ----------
    p : ScrewParams
        Validated physical parameters.

    """
    m, kmat, cmat = _mass_matrices(p)
    s = 1.0 / np.sqrt(m)
    w2 = np.linalg.eigvalsh(kmat * np.outer(s, s)).max()
    rate = np.linalg.eigvalsh(cmat * np.outer(s, s)).max()
    return math.sqrt(max(w2, 0.0)), max(rate, 0.0)


def auto_substep(p):
    """
    Return the largest stable substep [s]: 0.2 / omega_max, and 0.2 / damping rate.

    A stepper also bounds it by 0.2 / its rotor's magnetic frequency and 0.1 /
    the electrical frequency at the largest step rate.

    Capped at ``p.substep`` when that is set; 1 ms if nothing bounds it.

    Parameters
    ----------
    p : ScrewParams
        Validated physical parameters.

    """
    omega, rate = stiffest_mode(p)
    h = min(0.2 / omega if omega > 0 else math.inf, 0.2 / rate if rate > 0 else math.inf)
    if p.drive_type == 'stepper':
        # the rotor on its magnetic spring N_r (T_h + 4 T_d), and the electrical
        # frequency N_r w at the largest step rate: the current set points and the
        # back-EMF are held at their mid-substep values, an error of order (N_r w h)^2
        n_r = p.rotor_teeth
        w_mag = math.sqrt(n_r * (p.holding_torque + 4.0 * p.detent_torque) / p.motor_inertia)
        w_el = n_r * p.max_step_rate * p.step_angle
        h = min(h, 0.2 / w_mag, 0.1 / w_el)
    if p.substep > 0.0:
        h = min(h, p.substep)
    return h if math.isfinite(h) else 1e-3
