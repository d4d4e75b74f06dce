"""Stage 'backlash': the reversal hysteresis of the reversals, measured and twin."""
import numpy as np

from ....analysis import figures as F


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
    section['backlash_calibrated'] = ctx.calibrated.backlash
    section['backlash_fitted'] = False
    section['cannot'].append('the backlash was not fitted (it keeps its starting value): the '
                             'measured and twin hysteresis compare it; a vertical loaded axis '
                             'keeps the nut on one flank, so the play does not show there')
    if section['measured'] is None:
        section['cannot'].append('no target approached from both sides: no reversal error')
    sigma = ctx.noise.get('nut_position')
    if sigma and section['measured'] is not None:
        # each dwell's reading is a mean over ~200 samples; B is the difference of two
        n = max(1, int(np.sum(k)) // max(1, 4 * len(section['measured']['targets']) * 5))
        section['reversal_resolution_m'] = 2.0 * sigma / np.sqrt(n)
    return section
