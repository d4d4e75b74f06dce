"""Stage 'stepper': the pull-out curve, the load line and the rate where steps are lost."""
import math

import numpy as np

from ...pullout import pullout_curve
from ....core import geometry
from ....core.friction_law import FrictionLaw

#: Step rates of the curve, and how far past max_step_rate it runs (the knee of the motor
#: and driver may lie beyond the configured top rate).
RATES, BEYOND = 20, 4.0
#: The knee: the first rate whose pull-out torque is below this share of the curve's largest.
KNEE = 0.9


def load_torque(p, rate):
    """
    Return the motor torque [N m] the axis needs at ``rate`` full steps/s, accelerating.

    Raising the load: the thread torque at the sliding speed (mu'(v / sin
    lambda)), the bearing and collar friction, plus the total inertia
    reflected on the motor times the configured step acceleration.
    """
    omega = rate * p.step_angle
    v = omega * p.lead / (2.0 * math.pi)
    lam = p.lead_angle
    mu = FrictionLaw(p).mu(abs(v) / math.sin(lam))
    w = abs(p.moving_mass * p.gravity * math.sin(p.inclination) - p.external_force) + \
        p.guide_coulomb
    thread = geometry.raise_torque(w, p.r_m, mu, lam)
    j = p.motor_inertia + p.screw_inertia + p.moving_mass * p.lead_ratio ** 2
    return thread + p.bearing_coulomb + p.collar_mu * p.collar_radius * w + \
        j * p.step_acceleration * p.step_angle


def run(ctx):
    """Return the stepper section (None for a servo axis)."""
    p = ctx.calibrated
    if p.drive_type != 'stepper':
        return None
    section = {'title': 'Stepper', 'cannot': []}
    top = BEYOND * p.max_step_rate
    rates = list(np.linspace(top / RATES, top, RATES))
    rows = pullout_curve(p.replace(max_step_rate=top), rates)
    loads = [load_torque(p, r) for r in rates]
    section['curve'] = [dict(r, load_torque=lt) for r, lt in zip(rows, loads)]
    section['max_step_rate'] = p.max_step_rate
    peak = max(r['pullout_torque'] for r in rows)
    knee = [r['step_rate'] for r in rows if r['pullout_torque'] < KNEE * peak]
    section['knee'] = knee[0] if knee else None
    if not knee:
        section['cannot'].append(f'no knee up to {top:g} full steps/s ({BEYOND:g} times '
                                 'max_step_rate)')
    lose = [r['step_rate'] for r, lt in zip(rows, loads)
            if r['pullout_torque'] <= lt and r['step_rate'] <= p.max_step_rate]
    section['loses_steps_at'] = lose[0] if lose else None
    if lose:
        section['margin'] = lose[0] / p.max_step_rate
        section['verdict'] = (f'the load line crosses the pull-out curve at {lose[0]:.0f} full '
                              'steps/s: the axis loses steps from there on')
    else:
        section['margin'] = min(r['pullout_torque'] / lt for r, lt in zip(rows, loads)
                                if r['step_rate'] <= p.max_step_rate)
        section['verdict'] = ('the pull-out torque stays above the load line up to '
                              f'max_step_rate {p.max_step_rate:g} full steps/s (least ratio '
                              f'{section["margin"]:.3g})')
    if not p.encoder_counts:
        section['lost_steps'] = 'lost steps cannot be seen without an encoder'
        section['cannot'].append('lost steps cannot be seen without an encoder')
    section['cannot'].append('the pull-out curve is the model\'s motor and driver on an ideal '
                             'load; the stepper\'s electrical parameters were not fitted')
    return section
