"""Stage 'stability': where steady sliding stick-slips, over speed and friction spread."""
import math

import numpy as np

from ....analysis.excitation.base import nut_speed_limit
from ....analysis.stability.linear import linear_stability
from ....core.params import ParameterError

#: Speeds and static-friction values of the map.
SPEEDS, SPREAD = 40, 5


def _spread(ctx):
    """Return (mu_s values, what bounds them): the fit's 95 % interval, else the start alone."""
    p = ctx.calibrated
    if ctx.fit:
        res = ctx.fit['res']
        if 'mu_s' in res.names:
            vd = res.verdict('mu_s')
            if vd.identified and math.isfinite(vd.lower) and math.isfinite(vd.upper):
                lo, hi = vd.lower, vd.upper
                if hi > lo:
                    return list(np.linspace(lo, hi, SPREAD)), 'the 95 % interval of mu_s'
    return [p.mu_s], 'mu_s at its value (no interval)'


def run(ctx):
    """Return the stability map section: growth rate of steady sliding over (speed, mu_s)."""
    p = ctx.calibrated
    section = {'title': 'Stability', 'cannot': []}
    v_top = nut_speed_limit(p)
    v_low = max(1e-6, 0.05 * p.stribeck_velocity * math.sin(p.lead_angle))
    speeds = np.geomspace(v_low, v_top, SPEEDS)
    mus, bound = _spread(ctx)
    section.update(speeds=speeds.tolist(), mu_s=[float(m) for m in mus], spread=bound,
                   velocity_limit_speed=v_top, drive='velocity')
    grid = []
    for mu in mus:
        q = p.replace(mu_s=float(mu))
        row = []
        for v in speeds:
            try:
                row.append(float(linear_stability(q, float(v), 'velocity')['growth_rate']))
            except (ParameterError, ValueError):
                row.append(None)
        grid.append(row)
    section['growth_rate'] = grid
    bounds = []
    for row in grid:
        bad = [v for v, g in zip(speeds, row) if g is not None and g > 0.0]
        bounds.append(float(max(bad)) if bad else None)
    section['boundary_speed'] = bounds
    worst = max((b for b in bounds if b is not None), default=None)
    section['worst_boundary_speed'] = worst
    ops = _operating_speeds(ctx)
    section['operating_speeds'] = ops
    if worst is None:
        section['stick_slip'] = 'steady sliding is stable at every speed of the map'
    elif ops:
        slowest = min(ops)
        section['margin'] = slowest / worst
        section['stick_slip'] = (f'unstable (stick-slip) below {worst * 1e3:.3g} mm/s; the '
                                 f'slowest recorded operating speed {slowest * 1e3:.3g} mm/s is '
                                 f'{slowest / worst:.3g} times that')
    if not ops:
        section['cannot'].append('no sweep: no recorded operating speeds to measure the '
                                 'margin from')
    section['cannot'].append('linear stability of steady sliding toward +x under the velocity '
                             'loop; the nonlinear amplitude of the stick-slip (and '
                             'bistability) is not computed here (leadscrew_sim stability)')
    if len(mus) == 1:
        section['cannot'].append('mu_s has no interval: the friction spread is not mapped')
    return section


def _operating_speeds(ctx):
    """Return the sweep's commanded level speeds [m/s] (absolute, distinct)."""
    if 'sweep' not in ctx.windows:
        return []
    a, b = ctx.windows['sweep']
    ts, vs = ctx.commands['velocity']
    k = (ts >= a) & (ts <= b) & (vs != 0.0)
    return sorted({abs(float(v)) for v in vs[k]})
