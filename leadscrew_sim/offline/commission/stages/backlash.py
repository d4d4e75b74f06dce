"""Stage 'backlash': the reversal hysteresis of the reversals, measured and twin; the fit."""
import copy
import math
import os

import numpy as np

from .fit import FIT
from ..trim import write_window
from ...identify.run import fit_recording
from ....analysis import figures as F
from ....core.params import ScrewParams


def hysteresis(t, target, x):
    """Return the ISO 230-2 reversal figures of a positioning part as a dict [m], or None."""
    r = F.reversal_error(t, target, x)
    if r is None:
        return None
    return {'targets': list(r.targets), 'mean_up': list(r.mean_up),
            'mean_down': list(r.mean_down), 'reversal': list(r.reversal),
            'mean_reversal': r.mean_reversal, 'max_reversal': r.max_reversal}


def run(ctx, part='reversals', title='Backlash'):
    """Return the section of one positioning part: measured and twin reversal error."""
    section = {'title': title, 'cannot': []}
    if part not in ctx.windows:
        section['cannot'].append(f'no {part} segment: the reversal error is not measured')
        return section
    a, b = ctx.windows[part]
    m = ctx.measured
    k = m.window(a, b)
    t = m.time[k]
    section['measured'] = hysteresis(t, ctx.held('position', t), m.nut_position[k])
    if ctx.twin is not None:
        tt = ctx.twin_time
        kk = (tt >= a) & (tt <= b)
        section['twin'] = hysteresis(tt[kk], ctx.held('position', tt[kk]),
                                     ctx.twin['nut_position'][kk])
    section['backlash_fitted'] = False
    if part == 'reversals':
        fit_backlash(ctx, section)
    section['backlash_calibrated'] = ctx.calibrated.backlash
    if section['measured'] is None:
        section['cannot'].append('no target approached from both sides: no reversal error')
    sigma = ctx.noise.get('nut_position')
    if sigma and section['measured'] is not None:
        # each dwell's reading is a mean over ~200 samples; B is the difference of two
        n = max(1, int(np.sum(k)) // max(1, 4 * len(section['measured']['targets']) * 5))
        section['reversal_resolution_m'] = 2.0 * sigma / np.sqrt(n)
    return section


#: Least RMS move of the twin's nut over the reversals per unit of added play [-] at which
#: the play shows. Measured on tr12x3 (play 0.1 mm doubled): 0.014 on the vertical axis,
#: whose load keeps the nut on one flank, against 0.65 on a horizontal one.
LEAST_SHOW = 0.2
#: Least play added for the test of whether the play shows [m].
LEAST_ADDED = 5e-5


def play_shows(ctx):
    """
    Return (whether the play moves the twin's nut over the reversals, the move per play).

    Two re-simulations of the twin, at the calibrated backlash b and at b +
    max(b, LEAST_ADDED): the RMS of the difference of their nut positions
    over the reversals, over the play added. This costs two re-simulations;
    the fit, when the play does not act, costs thousands to say so.
    """
    a, b = ctx.windows['reversals']
    b0 = float(ctx.calibrated.backlash)
    added = min(max(b0, LEAST_ADDED), 0.9 * float(ctx.calibrated.pitch) - b0)
    if added <= 0.0:            # a play near the pitch already: let the fit judge it
        return True, math.nan
    xs = []
    for play in (b0, b0 + added):
        cols, tt = ctx.axis.resimulate(
            ScrewParams.from_dict({'backlash': play}, base=ctx.calibrated), ctx.fit)
        tt = tt - ctx.origin
        xs.append(np.asarray(cols['nut_position'])[(tt >= a) & (tt <= b)])
    per = float(np.sqrt(np.mean((xs[1] - xs[0]) ** 2))) / added if len(xs[0]) else 0.0
    return per >= LEAST_SHOW, per


def fit_backlash(ctx, section):
    """
    Fit the backlash on the recording up to the reversals' end, the friction held at the fit's.

    The play shows only where the nut is measured apart from the motor: with
    a linear scale. Without one, the nut position is the encoder's through
    the lead, with no play in it, and the section says so. A vertical loaded
    axis keeps the nut on one flank, so the fit finds no sensitivity there
    and says that. An identified backlash joins the calibrated set and
    fit.yaml, with its 95 % interval.
    """
    if ctx.fit is None:
        section['cannot'].append('the backlash was not fitted: no identify fit (no sweep) to '
                                 'hold the friction at')
        return
    if 'nut_position' not in ctx.fit['problem'].measurements.names:
        section['cannot'].append('the backlash cannot be seen without a linear scale: the '
                                 'nut position is then the encoder\'s through the lead, which '
                                 'has no play in it; it keeps its starting value')
        return
    shows, per = play_shows(ctx)
    if not shows:
        section['backlash_fit'] = {
            'value': None, 'lower': None, 'upper': None, 'verdict': 'not identifiable',
            'reason': f'the play does not show: more play moves the twin\'s nut over the '
                      f'reversals by {per:.3g} m per m (RMS), less than {LEAST_SHOW:g}',
            'window': [0.0, ctx.windows['reversals'][1]], 'wall_s': None,
            'held': {n: float(getattr(ctx.calibrated, n)) for n in FIT}}
        section['cannot'].append(f'backlash: not identified on the reversals: more play moves '
                                 f'the twin\'s nut there by {per:.3g} m per m (RMS), as when a '
                                 'load keeps the nut on one flank (a vertical axis); it keeps '
                                 'its starting value')
        return
    _a, b = ctx.windows['reversals']
    path = os.path.join(ctx.work, 'backlash_window.mcap')
    write_window(ctx.rec, path, ctx.origin + b)
    args = copy.copy(ctx.identify_args)
    held = [f'{n}={float(getattr(ctx.calibrated, n))!r}' for n in FIT]
    args.file, args.fit, args.set = path, 'backlash', list(args.set or []) + held
    out = fit_recording(args)
    res = out['res']
    i = list(res.names).index('backlash')
    vd, value = res.verdicts[i], float(res.values[i])
    section['backlash_fit'] = {
        'value': value if vd.identified else None,
        'lower': vd.lower if vd.identified and math.isfinite(vd.lower) else None,
        'upper': vd.upper if vd.identified and math.isfinite(vd.upper) else None,
        'verdict': vd.status, 'reason': getattr(vd, 'reason', '') or '',
        'window': [0.0, b], 'wall_s': out['wall'],
        'held': {n: float(getattr(ctx.calibrated, n)) for n in FIT}}
    if vd.identified:
        section['backlash_fitted'] = True
        ctx.calibrated = ScrewParams.from_dict({'backlash': value}, base=ctx.calibrated)
        ctx.backlash_fit = (value, vd.lower, vd.upper)
    else:
        section['cannot'].append(f'backlash: not identified on the reversals '
                                 f'({" ".join(str(vd.reason).split())}); it keeps its '
                                 'starting value (a vertical loaded axis keeps the nut on one '
                                 'flank, so the play does not show there)')
