"""
The parametric bootstrap of ``identify``'s intervals: refits of synthetic recordings.

The Jacobian's interval assumes residuals that are the sensor noise alone;
quantisation of a slow signal and a drive loop's response to its noisy
sensors break that. :func:`bootstrap` re-simulates the fit as the truth with
the recorded sensor model, refits each synthetic recording, and widens every
interval to the spread of those refits; :func:`resolution` then refits the
recording itself from off its fit and widens the interval of a parameter
those refits cannot bring back (a rough or flat cost) to their offset.
"""
import dataclasses

import numpy as np

from . import fit as ident
from .data import REL_MAX, t_quantile
from ...core.params import ScrewParams


#: Synthetic recordings of the parametric bootstrap of the intervals, and how far from the
#: fitted values (in half-widths of their intervals) each refit starts.
BOOTSTRAP, AWAY = 4, 2.0
#: The least half-width the refits' starts count with when the first refits stalled
#: [share of the value, or of the coordinate's typical size]: quantised sensors make the
#: cost flat in steps, and a refit that starts within such a step stays there, which
#: would hide the estimator's error.
MIN_HALF_WIDTH = 0.01
#: Refits that move a parameter, on average, by less than this share of their start's
#: offset stayed where they started (stalled): the signals are flat there at their
#: resolution. Refits that converge come back most of the way (they end within the
#: noise's spread, about a quarter of the offset of two half-widths).
STALLED = 0.25
#: Largest residual RMS / noise level of a refit that explained its synthetic recording (the
#: bar identify holds the recording's own fit to). A refit above it stopped in another
#: minimum: the search, not the noise, put it there; it is made again from the synthetic
#: recording's truth, and one still above is left out of the spread (the recording's own
#: fit is only accepted below the bar too).
LOST = 2.5
#: Fewest refits that explained their synthetic recordings for a parameter's spread.
MIN_KEPT = 2


def bootstrap(problem, res, names, start, coords, max_nfev, bounds):
    """
    Widen each interval to the spread of refits of synthetic recordings (a parametric bootstrap).

    Each of :data:`BOOTSTRAP` synthetic recordings re-simulates the commands at
    the fitted values with the recorded sensor model and its own seed (not the
    recording's; each quantiser's zero moved within a step by :func:`_dither`),
    so it holds what the recording would hold if the fit were
    the truth: sensor noise, quantisation, and in velocity and position mode
    that noise acting on the motion through the drive. Each is fitted the
    same way from the fitted values; the RMS of their errors delta_j about
    those values is the estimator's error s_b, which the Jacobian's interval
    misses where the residuals are not the noise it assumes (quantisation
    of a slow signal, the loop's response to its sensors). The interval
    becomes value +- max(w, t_K s_b) (t quantile of K degrees of freedom: the
    errors' mean is known to be 0). The refits start AWAY half-widths off;
    if they stay where they started for a parameter (they move it on average
    by less than STALLED of their offset: flat signals at their resolution),
    they are made again from at least MIN_HALF_WIDTH of the values off, and
    that parameter takes the new refits' errors; where those stay too, value
    +- t_K s_b is about their starts' spread: said to be a lower bound. A
    refit that does not explain its synthetic recording (an RMS above
    :data:`LOST` noise levels) stopped in another minimum of a rough cost; it
    is made again from the fitted values (the synthetic recording's truth),
    and if that does not explain it either it is left out: K counts the
    others, and a parameter with fewer than :data:`MIN_KEPT` of them is not
    identifiable, as nothing bounds its error.
    Returns the new FitResult.

    Parameters
    ----------
    problem : Problem
        The recording's fit problem of ``identify`` (its ``measurements``,
        ``replay``, ``residuals``, ``use_data``); its measured data are swapped
        for each synthetic recording and restored.
    res : FitResult
        The fit of the recording.
    names : list of str
        The fitted parameters.
    start : ScrewParams
        The starting and fixed values.
    coords : list of Coordinate
        The fitted parameters' coordinates of the first fit.
    max_nfev : int or None
        Most re-simulations per refit (None: 50 per parameter).
    bounds : dict
        name -> (lower, upper) of each fitted parameter, the first fit's.

    """
    args = (problem, res, names, start, coords, max_nfev, bounds)
    errors, stalled, nfev = _refit_errors(*args, floor=0.0)
    identified = np.array([vd.identified for vd in res.verdicts])
    if np.any(stalled & identified):     # again from farther off; those parameters take these
        errors2, stalled2, nfev2 = _refit_errors(*args, floor=MIN_HALF_WIDTH)
        errors = np.where(stalled, errors2, errors)
        stalled = stalled & stalled2
        nfev += nfev2 - res.nfev
    kept = np.sum(np.isfinite(errors), axis=0)       # per parameter: the refits that count
    s_b = np.sqrt(np.nansum(errors ** 2, axis=0) / np.maximum(kept, 1))
    verdicts, lower, upper = [], [], []
    for i, (v, vd, c) in enumerate(zip(res.values, res.verdicts, coords)):
        problem.bootstrap[c.name] = float(s_b[i]) if kept[i] else float('nan')
        if vd.identified and kept[i] < MIN_KEPT:
            vd = dataclasses.replace(vd, identified=False, reason=(
                f'not identifiable: {len(errors) - kept[i]} of {len(errors)} refits of '
                'synthetic recordings did not explain theirs (they stopped in other minima '
                'of a rough cost): too few are left to bound the error'))
        elif vd.identified and t_975(kept[i]) * s_b[i] > 0.5 * (vd.upper - vd.lower):
            why = 'synthetic' if stalled[i] else ''         # never narrower
            vd = _widened(vd, v, c, t_975(kept[i]) * float(s_b[i]), float(s_b[i]), why,
                          refits=(int(kept[i]), len(errors)))
        verdicts.append(vd)
        lower.append(vd.lower)
        upper.append(vd.upper)
    values = [v if vd.identified else v0
              for v, v0, vd in zip(res.values, res.initial, verdicts)]
    res = dataclasses.replace(res, values=values, lower=lower, upper=upper,
                              verdicts=verdicts, nfev=nfev)
    return resolution(problem, res, names, start, coords, max_nfev, bounds)


def resolution(problem, res, names, start, coords, max_nfev, bounds):
    """
    Widen each interval to what the recording's own refits from off its fit leave open.

    Two refits of the recording itself start from every identified parameter
    moved by its offset, max(AWAY half-widths, MIN_HALF_WIDTH of its size),
    up and then down. A parameter they move on average by less than STALLED
    of its offset stays where it starts: the recording's cost is flat or
    rough at that scale (a drive loop over coarse sensors makes a stick-slip
    recording's cost rough: its local minima lie closer together than the
    noise's spread), and the fit cannot tell the fitted value from one that
    far off. Its interval becomes at least value +- the offset, said to be a
    lower bound. The synthetic recordings of :func:`bootstrap` cannot show
    this: their fits start near their truth, the recording's from afar.
    A parameter the refits do bring back, but to a value farther from the fit
    than its interval reaches, gets an interval reaching that far when the
    refit's cost is within the cost's own spread of the fit's
    (:func:`_cost_spread`): the data do not rank the two ends, so the
    recording does not single out a value closer than that (a rough cost's
    other minimum, or a valley too flat to follow).
    Returns the new FitResult. The arguments are :func:`bootstrap`'s.
    """
    identified = np.array([vd.identified for vd in res.verdicts])
    if not np.any(identified):
        return res
    offsets = np.array([max(AWAY * _half(vd, v, c, 0.0), MIN_HALF_WIDTH * max(abs(v), c.typical))
                        if vd.identified else 0.0
                        for c, v, vd in zip(coords, res.values, res.verdicts)])
    starts, ends, costs, nfev = [], [], [], res.nfev
    for sign in (1.0, -1.0):
        away = {c.name: min(c.upper, max(c.lower, v + sign * off))
                for c, v, off in zip(coords, res.values, offsets)}
        refit = ident.fit(problem.residuals, ident.coordinates(
            names, ScrewParams.from_dict(away, base=start), bounds),
            max_nfev=max_nfev, rounds=1, scan=False, jac_steps=problem.jac_steps)
        starts.append([away[c.name] for c in coords])
        ends.append(refit.values)
        costs.append(_cost(refit))
        nfev += refit.nfev
    stalled = _stalled(np.array(starts), np.array(ends), np.array(res.values)) & identified
    problem.resolution = {c.name: float(off) for c, off, s in zip(coords, offsets, stalled) if s}
    ceiling = _cost(res) * (1.0 + _cost_spread(res))     # ends the data do not rank below
    rivals = [e for e, cost in zip(ends, costs) if cost <= ceiling]
    reach = (np.max(np.abs(np.array(rivals) - np.array(res.values)), axis=0) if rivals
             else np.zeros(len(res.values)))
    verdicts = list(res.verdicts)
    for i, (v, vd, c) in enumerate(zip(res.values, res.verdicts, coords)):
        half = 0.5 * (vd.upper - vd.lower)
        if stalled[i] and offsets[i] > half:
            verdicts[i] = _widened(vd, v, c, float(offsets[i]), vd.std, 'recording')
        elif vd.identified and reach[i] > half:
            verdicts[i] = _widened(vd, v, c, float(reach[i]), vd.std, 'reach')
    values = [v if vd.identified else v0
              for v, v0, vd in zip(res.values, res.initial, verdicts)]
    return dataclasses.replace(res, values=values, lower=[vd.lower for vd in verdicts],
                               upper=[vd.upper for vd in verdicts], verdicts=verdicts,
                               nfev=nfev)


def _cost(res):
    """Return the fit's cost: the sum over the signals of their mean squared residual [noise^2]."""
    return float(np.sum(np.asarray(res.rms, dtype=float) ** 2))


def _cost_spread(res):
    """
    Return the relative spread sqrt(2 / n_eff) of the fit's cost under another noise draw.

    A chi-square of n_eff independent residuals (the residuals over their
    correlation length) has a relative standard deviation sqrt(2 / n_eff):
    two ends whose costs differ by less could swap order with another
    draw, so the data do not rank them.
    """
    n_eff = max(1.0, res.n_residuals / max(1, res.bandwidth))
    return float(np.sqrt(2.0 / n_eff))


def _half(vd, v, c, floor):
    """Return the half-width of ``vd``'s interval, at least ``floor`` of the value's size."""
    return max(0.5 * (vd.upper - vd.lower), floor * max(abs(v), c.typical))


def _stalled(starts, ends, fitted):
    """
    Return per parameter whether refits from ``starts`` to ``ends`` stayed where they started.

    starts, ends: arrays (refits, parameters); fitted: the values the starts
    are offset from. Stalled: moved on average by less than STALLED of the
    offset (a parameter not offset never stalls).
    """
    off = np.abs(starts - fitted)
    moved = np.abs(ends - starts) / np.where(off > 0.0, off, np.inf)
    return (np.mean(moved, axis=0) < STALLED) & np.all(off > 0.0, axis=0)


def _refit_errors(problem, res, names, start, coords, max_nfev, bounds, floor):
    """
    Return the refits' errors, whether each parameter stalled, and the fit's nfev with theirs.

    The arguments are :func:`bootstrap`'s; ``floor``: the least half-width a
    refit's start counts with [share of the value, or of the typical size].
    errors: array (BOOTSTRAP, parameters) of refit less fitted value, a row
    of NaN for a refit that did not explain its synthetic recording (RMS
    above :data:`LOST` noise levels); stalled: per parameter, True if the
    other refits moved it on average by less than STALLED of their offset
    (they stayed where they started).
    """
    fitted = dict(zip(res.names, res.values))
    sensors = dict(getattr(problem, 'loop_sensors', None) or
                   {n: getattr(problem.recorded, n) for n in ident.IDEAL_SENSORS})
    base = dict(sensors)
    meas = problem.measurements
    recorded = (meas.data, meas.mask, problem.anchoring)
    errors, starts, ends, nfev = [], [], [], res.nfev
    try:
        for j in range(BOOTSTRAP):
            sensors['sensor_seed'] = (problem.recorded.sensor_seed + 1 + j) % 2 ** 31
            sensors.update(_dither(sensors, base, sensors['sensor_seed'],
                                   getattr(problem, 'foreign', False)))
            synthetic = problem.replay(dict(fitted, **sensors), plain=True)
            cols = {s: np.asarray(synthetic[c][:problem.n]) for s, c, _u in ident.SIGNALS}
            data = np.array([cols[s] for s in meas.names])
            if problem.anchoring is None:
                meas.data = np.where(meas.mask, data, 0.0)
            else:           # its own rests, and the steps they determine
                problem.use_data(data, fitted)
            away = {}
            for i, (c, v, vd) in enumerate(zip(coords, res.values, res.verdicts)):
                sign = (1.0, -1.0)[(j + (i if j >= 2 else 0)) % 2]
                step = AWAY * _half(vd, v, c, floor) if vd.identified else 0.0
                away[c.name] = min(c.upper, max(c.lower, v + sign * step))
            syn = ident.fit(problem.residuals, ident.coordinates(
                names, ScrewParams.from_dict(away, base=start), bounds),
                max_nfev=max_nfev, rounds=1, scan=False, jac_steps=problem.jac_steps)
            nfev += syn.nfev
            if np.max(np.asarray(syn.rms, dtype=float)) > LOST:
                # the search from off the truth stopped in another minimum; from the
                # values the recording was made with, the fit finds the minimum the
                # noise moved there, whose offset is the estimator's error
                syn = ident.fit(problem.residuals, ident.coordinates(
                    names, ScrewParams.from_dict(fitted, base=start), bounds),
                    max_nfev=max_nfev, rounds=1, scan=False, jac_steps=problem.jac_steps)
                nfev += syn.nfev
                lost = np.max(np.asarray(syn.rms, dtype=float)) > LOST
                errors.append(np.full(len(coords), np.nan) if lost else
                              np.array(syn.values) - np.array(res.values))
                continue
            errors.append(np.array(syn.values) - np.array(res.values))
            starts.append([away[c.name] for c in coords])
            ends.append(syn.values)
    finally:
        meas.data, meas.mask, problem.anchoring = recorded
    stalled = (_stalled(np.array(starts), np.array(ends), np.array(res.values)) if starts
               else np.zeros(len(coords), dtype=bool))
    return np.array(errors), stalled, nfev


def _dither(sensors, base, seed, foreign=False):
    """
    Return the quantisers' biases of a synthetic recording: the recorded ones moved within a step.

    A quantiser without noise reads the same trajectory the same way with
    every seed, so synthetic recordings of noise-free quantisers would all
    be one recording and their refits would show nothing of the
    quantisation's error. Its phase is what a real recording does not fix
    (the homing's zero lies anywhere within a step): each synthetic
    recording moves the bias of a quantiser without noise by a uniform share
    of one step (seeded by ``seed``); the free offsets take the bias itself
    up. A noisy quantiser's phase is left where the recording's parameters
    put it, unless the recording is ``foreign``: its biases are not known,
    and synthetic recordings that all share one phase resemble one another
    more than they resemble the recording (the reversals of
    ``bench/bench_coverage.py``: 3.8e-3 to 4.9e-3 rad apart on the screw
    angle with one phase, 5.1e-3 to 5.9e-3 with a phase each, against 6.6e-3
    to 7.5e-3 from the recording).
    """
    rng = np.random.default_rng(seed)
    out = {}
    u_enc, u_scale = rng.uniform(0.0, 1.0, 2)
    if base.get('encoder_counts') and (foreign or not base.get('encoder_noise')):
        out['encoder_bias'] = base.get('encoder_bias', 0.0) + \
            u_enc * 2.0 * np.pi / base['encoder_counts']
    if base.get('scale_resolution') and (foreign or not base.get('scale_noise')):
        out['scale_bias'] = base.get('scale_bias', 0.0) + u_scale * base['scale_resolution']
    return out


def _widened(vd, v, c, hw, s_b, stalled='', refits=(BOOTSTRAP, BOOTSTRAP)):
    """
    Return the verdict of value ``v`` of coordinate ``c`` with the half-width ``hw``.

    ``refits``: (those that count, those made) of the synthetic recordings.

    ``stalled``: '' when ``hw`` is the refits' spread; 'synthetic' when the
    refits of the synthetic recordings stayed where they started for this
    parameter, 'recording' when the recording's own did: ``hw`` is then
    about the offset of those starts, a lower bound of the interval, not a
    spread; 'reach' when the recording's own refits came back but ended
    ``hw`` from the fit.
    """
    lo, hi = max(c.lower, v - hw), min(c.upper, v + hw)
    rel = 0.5 * (hi - lo) / max(abs(v), c.typical)
    ok = bool(rel <= REL_MAX)
    if stalled == 'reach':
        why = (f'identified: 95 % interval +-{100 * rel:.3g} % (refits of the recording '
               'started off the fit on either side ended that far from it: the recording\'s '
               'cost does not single out a value closer than that)' if ok else
               f'not identifiable: refits of the recording ended +-{100 * rel:.3g} % from the '
               'fit: its cost does not single out a value closer than that')
    elif stalled:
        refits = (f'refits of {_counted(refits)} synthetic recordings'
                  if stalled == 'synthetic' else 'refits of the recording')
        why = (f'identified: 95 % interval +-{100 * rel:.3g} % or wider ({refits} started '
               'that far off stayed there: the signals are flat or rough there at their '
               'resolution)' if ok else
               f'not identifiable: {refits} started +-{100 * rel:.3g} % off stayed there: '
               'the signals are flat or rough there at their resolution')
    elif ok:
        why = (f'identified: 95 % interval +-{100 * rel:.3g} % (the spread of '
               f'{_counted(refits)} refits of synthetic recordings)')
    else:
        why = (f'not identifiable: refits of {_counted(refits)} synthetic recordings spread '
               f'+-{100 * rel:.3g} %: the noise, not the data, decides it')
    return dataclasses.replace(vd, identified=ok, reason=why, lower=lo, upper=hi, rel=rel,
                               std=s_b)


def _counted(refits):
    """Return how many refits count, and why the others do not ('4', '3 (1 lost ...)')."""
    kept, made = refits
    if kept == made:
        return f'{kept}'
    return (f'{kept} (of {made}; the others stopped in other minima, not explaining their '
            'recordings)')


def t_975(dof):
    """Return the 97.5 % quantile of the t distribution of ``dof`` degrees of freedom."""
    return t_quantile(0.95, dof)
