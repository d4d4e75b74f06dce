"""
The segments of a measured run: its stretches of motion between rests.

A state is at rest when the measured position (the nut's, else the
screw's) moves by less than :data:`REST_SHARE` of its range (and less than
four times its median step-to-step change, its noise) within
:data:`REST_TIME` around it; the segments are the stretches of motion
between rests. (The measured velocities of a quantising sensor are too
noisy for this.) The twin report and the replay's start both use them.
"""
import numpy as np

__all__ = ['motion_segments', 'REST_SHARE', 'REST_TIME']

#: Shortest rest that separates two segments [s].
REST_TIME = 0.2
#: A position change below this share of the position's range counts as at rest [-].
REST_SHARE = 0.02


def motion_segments(time, values, inside):
    """Return [(first, end)] index ranges of the states between rests (see the module)."""
    idx = np.flatnonzero(inside)
    if not len(idx):
        return []
    whole = [(int(idx[0]), int(idx[-1]) + 1)]
    name = 'nut_position' if 'nut_position' in values else 'screw_angle'
    y = values.get(name)
    if y is None or len(idx) < 3:
        return whole
    t, y = time[idx], y[idx]
    ok = np.isfinite(y)
    t, y, idx = t[ok], y[ok], idx[ok]
    span = float(np.ptp(y)) if len(y) else 0.0
    if not span > 0:
        return whole
    noise = float(np.median(np.abs(np.diff(y)))) if len(y) > 1 else 0.0
    threshold = max(REST_SHARE * span, 4.0 * noise)
    # moving: the position changes by more than the threshold within half a rest either way
    half = REST_TIME / 2
    lo = np.searchsorted(t, t - half)
    hi = np.searchsorted(t, t + half, side='right') - 1
    run_max = _window(y, lo, hi, np.maximum)
    run_min = _window(y, lo, hi, np.minimum)
    moving = (run_max - run_min) > threshold
    out, start = [], None
    for i in range(len(t)):
        if moving[i] and start is None:
            start = i
        elif not moving[i] and start is not None:
            out.append((int(idx[start]), int(idx[i - 1]) + 1))
            start = None
    if start is not None:
        out.append((int(idx[start]), int(idx[-1]) + 1))
    return out or whole


def _window(y, lo, hi, op):
    """Return op (np.maximum or np.minimum) of ``y[lo[i]:hi[i] + 1]`` for every i."""
    n = len(y)
    out = y.copy()
    # sparse table of the windows' extremes: O(n log n)
    table = [y]
    width = 1
    while 2 * width <= n:
        prev = table[-1]
        table.append(op(prev[:-width], prev[width:]))
        width *= 2
    length = hi - lo + 1
    level = np.floor(np.log2(np.maximum(length, 1))).astype(int)
    for j in np.unique(level):
        sel = level == j
        w = 1 << j
        a = table[j][lo[sel]]
        b = table[j][hi[sel] - w + 1]
        out[sel] = op(a, b)
    return out
