"""
The operating point of steady sliding (doc/stability.md).

The nut slides at a constant speed v [m/s] (sign = direction along +x); the
screw turns at q' = v / r_t (q sense, r_t = l / 2 pi) and the thread slides at
v_s0 = v / sin(lambda) (rigid contact). The nut rests on the loaded flank:
the one whose normal force balances the axial load W the thread carries,
W = c_x v + F_x0 sgn(v) - F_g - F_ext (guide, gravity, external force). The
screw's torque balance gives the coupling twist and the motor torque; with
the servo drive in velocity mode that torque is the integral term of its PI
loop (or, without an integral, the proportional term of a raised reference).

With an anti-backlash (split) nut both halves slide at v, each on the flank
its own axial load picks: nut A carries W plus the preload spring's force
F_s, half-nut B its weight less F_s, where F_s = F_p + k_p (b - (x_B - x_A))
follows from the two contact deflections (:func:`split_nut`).
"""
import math

from ...core.friction_law import FrictionLaw
from ...core.params import ParameterError

__all__ = ['DRIVES', 'operating_point', 'split_nut']

#: The drives of the analysis: the servo's velocity loop, or a prescribed motor angle.
DRIVES = ('velocity', 'ideal')


def load_factor(mu, tan_l, sigma_s):
    """
    Return the signed load factor G of doc/model.md section 7 (T = r_m W G).

    G+ = (tan + mu) / (1 - mu tan) when the drive moves against the load
    (sigma_s = +1), -G- = (tan - mu) / (1 + mu tan) when the load assists (-1).

    Parameters
    ----------
    mu : float
        Apparent friction coefficient mu' [-].
    tan_l : float
        tan(lambda) [-].
    sigma_s : float
        +1 against the load, -1 with it.

    """
    return (tan_l + sigma_s * mu) / (1.0 - sigma_s * mu * tan_l)


def _axial_load(p, v, s):
    """Return W [N]: c_x v + F_x0 s - F_g - F_ext, the force the thread supplies along +x."""
    f_g = -(p.nut_mass + p.payload_mass) * p.gravity * math.sin(p.inclination)
    return p.guide_viscous * v + p.guide_coulomb * s - f_g - p.external_force


def _drive_state(p, drive, v, omega, torque):
    """Return (w_ref [rad/s], integral [rad]) of the velocity loop holding omega at torque."""
    kv, ti = p.velocity_gain, p.velocity_integral_time
    if ti > 0.0:
        w_ref, integral = omega, (torque * ti / kv if kv > 0.0 else 0.0)
    else:
        w_ref, integral = omega + (torque / kv if kv > 0.0 else 0.0), 0.0
    if drive == 'velocity' and kv == 0.0:
        raise ParameterError('velocity_gain', '0 N m s/rad: the velocity loop cannot hold a '
                             'speed (give a gain > 0, or use the ideal drive)')
    if drive == 'velocity' and abs(w_ref) > p.reference_speed_limit:
        name = ('velocity_limit' if p.reference_speed_limit == p.velocity_limit
                else 'max_screw_velocity')
        raise ParameterError(name, f'{getattr(p, name)!r} rad/s is below the '
                             f'{abs(w_ref):.4g} rad/s reference that {v!r} m/s needs')
    return w_ref, integral


def _flank(load, s, mu0, lam, v):
    """
    Return (sigma, |N0| [N]) of a nut body whose thread supplies ``load`` [N] along +x.

    sigma = +1: the leading flank carries it, -1 the trailing one; |N0| =
    |W| / (cos(lambda) - sigma s mu' sin(lambda)) while sliding in direction s.
    """
    sigma = 1.0 if load > 0.0 else -1.0
    den = math.cos(lam) - sigma * s * mu0 * math.sin(lam)
    if den <= 0.0:
        raise ParameterError('mu_k', f"mu' tan(lambda) = {mu0 * math.tan(lam):.3g} >= 1 at "
                             f'{v!r} m/s: the thread jams')
    return sigma, abs(load) / den


def split_nut(p, load, s, mu0, v):
    """
    Return (((sigma_A, |N_A|), (sigma_B, |N_B|)), F_s [N]) of a split nut sliding steadily.

    Nut A's thread supplies W_A = load + F_s, half-nut B's W_B = m_b g
    sin(beta) - F_s. With the flanks fixed, F_s = F_p + k_p (b - (delta_B -
    delta_A)), delta_i = -sigma_i (b/2 + |N_i| cos(lambda) / k) and |N_i| =
    sigma_i W_i / d_i are linear in F_s: solved exactly; the flanks start from
    F_s = F_p and are updated until they agree with the loads.
    """
    lam = p.lead_angle
    cl, sl = math.cos(lam), math.sin(lam)
    kp, b = p.preload_stiffness, p.backlash
    load_b = p.second_nut_mass * p.gravity * math.sin(p.inclination)
    c = kp * cl / p.contact_stiffness
    f_s = p.preload_force
    for _ in range(4):
        sa = 1.0 if load + f_s > 0.0 else -1.0
        sb = 1.0 if load_b - f_s > 0.0 else -1.0
        da, db = cl - sa * s * mu0 * sl, cl - sb * s * mu0 * sl
        if min(da, db) <= 0.0:
            raise ParameterError('mu_k', f"mu' tan(lambda) = {mu0 * math.tan(lam):.3g} >= 1 "
                                 f'at {v!r} m/s: the thread jams')
        f_s = ((p.preload_force + kp * b - kp * (sa - sb) * b / 2.0
                - c * (load / da - load_b / db)) / (1.0 + c * (1.0 / da + 1.0 / db)))
        if (load + f_s > 0.0) == (sa > 0.0) and (load_b - f_s > 0.0) == (sb > 0.0):
            break
    else:
        raise ParameterError('preload_force', f'{p.preload_force!r} N: no steady sliding of '
                             f'the split nut at {v!r} m/s (its flanks do not settle)')
    if load + f_s == 0.0 or load_b - f_s == 0.0:
        raise ParameterError('speed', f'{v!r} m/s leaves a half-nut unloaded: it floats in '
                             'the backlash')
    return ((sa, abs(load + f_s) / da), (sb, abs(load_b - f_s) / db)), f_s


def _stepper_state(p, v, omega, torque):
    """
    Return (k_e [N m/rad], B [N m s/rad], load angle [rad]) of a stepper turning at omega.

    The step generator turns the commanded angle at omega and the chopper keeps
    the run current, so the rotor lags by the load angle phi with T_h sin(N_r
    phi) = torque + B omega (the thread and bearings' need plus the rotor's
    damping) and sees the magnetic stiffness k_e = N_r T_h cos(N_r phi). The
    detent torque, periodic at 4 N_r omega, averages out and is left out.
    Refused: a rate beyond max_step_rate, a torque at or beyond the holding
    torque (the stepper loses steps), and a speed where the supply voltage
    cannot drive the run current against the winding's impedance and the
    back-EMF: I sqrt(R^2 + (N_r omega L)^2) + K_m |omega| > V.
    """
    nr, t_h = p.rotor_teeth, p.holding_torque
    w_max = p.max_step_rate * p.step_angle
    if abs(omega) > w_max:
        raise ParameterError('max_step_rate', f'{p.max_step_rate!r} full steps/s is below the '
                             f'{abs(omega) / p.step_angle:.4g} full steps/s {v!r} m/s needs')
    need = torque + p.rotor_damping * omega
    if abs(need) >= t_h:
        raise ParameterError('holding_torque', f'{t_h!r} N m is below the {abs(need):.4g} N m '
                             f'steady sliding at {v!r} m/s needs: the stepper loses steps')
    volts = (p.run_current * math.hypot(p.phase_resistance, nr * omega * p.phase_inductance)
             + p.torque_constant * abs(omega))
    if volts > p.supply_voltage:
        raise ParameterError('speed', f'{v!r} m/s needs {volts:.4g} V per phase to keep the run '
                             f'current, above supply_voltage {p.supply_voltage!r} V (the '
                             'stepper\'s torque falls there; the linear model does not hold)')
    phi = math.asin(need / t_h) / nr
    return nr * t_h * math.cos(nr * phi), p.rotor_damping, phi


def operating_point(params, speed, drive='velocity'):
    """
    Return the steady sliding state of the axis at nut speed ``speed``, q sense.

    Parameters
    ----------
    params : ScrewParams
        The axis.
    speed : float
        Nut speed [m/s], nonzero; its sign is the direction along +x.
    drive : str
        'velocity' (the servo's velocity loop holds the speed) or 'ideal'
        (the motor angle is prescribed).

    Returns
    -------
    dict
        speed, omega (q' [rad/s]), s (sgn v), sigma (+1 leading flank loaded,
        -1 trailing), vs0 [m/s], mu0 [-], slope (dmu'/dv [s/m]), load W [N],
        N0 (signed normal force [N]), Fa0 (axial thread force [N]), torque
        (motor torque [N m], q sense), twist (q_m - q [rad]), delta0 (x - r_t q
        [m]), G, J_e [kg m^2] and the drive's w_ref [rad/s] and integral [rad];
        of nut A, and half-nut B with a split nut: nuts ((sigma, |N0| [N]) each),
        deltas (each x - r_t q [m]) and spring (the preload force F_s [N], 0
        for a single nut); stepper: (k_e [N m/rad], B [N m s/rad], load angle
        [rad]) when a stepper holds the speed (drive 'velocity' on a stepper
        axis), else None.

    Raises
    ------
    ParameterError
        For a zero speed, an unknown drive, an unloaded thread, a
        torque beyond max_torque or (velocity drive) a reference beyond
        velocity_limit.

    """
    p = params
    v = float(speed)
    if not (math.isfinite(v) and v != 0.0):
        raise ParameterError('speed', f'{speed!r} m/s must be nonzero and finite')
    if drive not in DRIVES:
        raise ParameterError('drive', f'{drive!r} is not one of {", ".join(DRIVES)}')
    law = FrictionLaw(p)
    lam = p.lead_angle
    sl, cl, tl = math.sin(lam), math.cos(lam), math.tan(lam)
    rt, rm = p.lead_ratio, p.r_m
    s = 1.0 if v > 0.0 else -1.0
    omega = v / rt
    vs0 = v / sl
    mu0 = law.mu(vs0)
    load = _axial_load(p, v, s)
    if p.anti_backlash:
        nuts, spring = split_nut(p, load, s, mu0, v)
    else:
        if load == 0.0:
            raise ParameterError('speed', f'{v!r} m/s leaves the thread unloaded (no axial '
                                 'load): the nut floats in the backlash; add a load or '
                                 'guide damping')
        nuts, spring = (_flank(load, s, mu0, lam, v),), 0.0
    fa0 = sum(sg * n * cl - mu0 * n * s * sl for sg, n in nuts)
    t_thread = sum(rm * (-sg * n * sl - mu0 * n * s * cl) for sg, n in nuts)
    t_res = p.bearing_viscous * omega + (p.bearing_coulomb
                                         + p.collar_mu * p.collar_radius * abs(fa0)) * s
    torque = t_res - t_thread
    stepping = p.drive_type == 'stepper' and drive == 'velocity'
    if abs(torque) > p.max_torque and not stepping:      # a stepper: its holding torque
        raise ParameterError('max_torque', f'{p.max_torque!r} N m is below the {abs(torque):.4g}'
                             f' N m steady sliding at {v!r} m/s needs')
    rigid = p.coupling_stiffness == 0.0
    twist = 0.0 if rigid else torque / p.coupling_stiffness
    deltas = [-sg * (p.backlash / 2.0 + n * cl / p.contact_stiffness) for sg, n in nuts]
    masses = (p.nut_mass + p.payload_mass, p.second_nut_mass)
    g = load_factor(mu0, tl, nuts[0][0] * s)
    j_e = p.screw_inertia + (p.motor_inertia if rigid else 0.0) + rm * rt * sum(
        m * load_factor(mu0, tl, sg * s) for m, (sg, _) in zip(masses, nuts))
    stepper = None
    if stepping:
        w_ref, integral, stepper = omega, 0.0, _stepper_state(p, v, omega, torque)
    else:
        w_ref, integral = _drive_state(p, drive, v, omega, torque)
    sigma, n_abs = nuts[0]
    return dict(speed=v, omega=omega, s=s, sigma=sigma, vs0=vs0, mu0=mu0,
                slope=law.slope(vs0), load=load, N0=sigma * n_abs, Fa0=fa0, torque=torque,
                twist=twist, delta0=deltas[0], G=g, J_e=j_e, w_ref=w_ref, integral=integral,
                rigid=rigid, drive=drive, nuts=tuple(nuts), deltas=tuple(deltas),
                spring=spring, stepper=stepper)
