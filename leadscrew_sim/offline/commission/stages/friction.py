"""Stage 'friction': Stribeck points, breakaway torques, efficiencies and self-locking."""
import math

from ....analysis import figures as F
from ....core import geometry
from ....core.friction_law import FrictionLaw
from ....analysis.excitation.profiles import static_breakaway


def efficiency_closed_form(params, speed):
    """
    Return (forward, back-driving) efficiency of the thread at nut speed ``speed`` [m/s].

    eta = tan(lambda) (1 - mu' tan lambda) / (tan lambda + mu') raising,
    eta_b = (tan lambda - mu') / (tan lambda (1 + mu' tan lambda)) lowering, with
    mu' the apparent sliding coefficient at the sliding speed v / sin(lambda).
    """
    lam = params.lead_angle
    mu = FrictionLaw(params).mu(abs(speed) / math.sin(lam))
    return geometry.efficiency(mu, lam), geometry.backdrive_efficiency(mu, lam)


def run(ctx):
    """Return the friction section: measured against the calibrated twin's closed forms."""
    p = ctx.calibrated
    m = ctx.measured
    section = {'title': 'Friction', 'cannot': []}
    t_up, t_down = static_breakaway(p)
    section['static_band_twin'] = {'up': t_up, 'down': t_down}
    law = FrictionLaw(p)
    section['self_locking'] = bool(geometry.is_self_locking(law.mu(0.0), p.lead_angle))
    section['self_locking_in_motion'] = bool(geometry.is_self_locking(
        law.mu(1e3 * p.stribeck_velocity), p.lead_angle))
    load = F.axial_load(p)
    if 'sweep' in ctx.windows:
        a, b = ctx.windows['sweep']
        k = m.window(a, b)
        t = m.time[k]
        cmd = ctx.held('velocity', t)
        pts = F.stribeck_points(t, cmd, m.motor_torque[k], m.motor_velocity[k],
                                m.nut_velocity[k])
        twin = _twin_points(ctx, a, b)
        section['stribeck'] = [{'command': q.command, 'speed': q.speed, 'torque': q.torque,
                                'torque_std': q.torque_std} for q in pts]
        section['stribeck_twin'] = [{'command': q.command, 'speed': q.speed, 'torque': q.torque}
                                    for q in twin]
        rows, best = F.efficiencies(pts, load) if load else ([], {})
        section['efficiency_measured'] = best
        section['efficiency_twin'] = F.efficiencies(twin, load)[1] if load else {}
        if pts:
            fastest = max(abs(q.speed) for q in pts)
            fwd, back = efficiency_closed_form(p, fastest)
            section['efficiency_thread'] = {'speed': fastest, 'forward': fwd, 'backdrive': back}
        if not load:
            section['cannot'].append('no axial load: the efficiencies are undefined')
    else:
        section['cannot'].append('no sweep: no Stribeck points and no measured efficiency')
    if 'breakaway' in ctx.windows:
        a, b = ctx.windows['breakaway']
        k = m.window(a, b)
        t = m.time[k]
        sigma = ctx.noise.get('nut_position', 0.0)
        threshold = max(1e-6, 5.0 * sigma)
        br = F.breakaway_torques(t, ctx.held('torque', t), m.motor_torque[k], m.nut_position[k],
                                 threshold)
        section['breakaway_threshold_m'] = threshold
        section['breakaway'] = {('+' if s > 0 else '-'): (None if x is None else x.torque)
                                for s, x in br.items()}
        for s, x in section['breakaway'].items():
            if x is None:
                section['cannot'].append(f'breakaway toward {s}theta: the nut did not move by '
                                         f'{threshold * 1e6:.3g} um on the ramp')
    else:
        section['cannot'].append('no breakaway segment (a stepper takes no torque commands): '
                                 'the breakaway torques are not measured, only the twin\'s '
                                 'static band')
    return section


def _twin_points(ctx, a, b):
    if ctx.twin is None:
        return []
    t = ctx.twin_time
    k = (t >= a) & (t <= b)
    c = ctx.twin
    return F.stribeck_points(t[k], ctx.held('velocity', t[k]), c['motor_torque'][k],
                             c['motor_velocity'][k], c['nut_velocity'][k])
