"""
The parametric bootstrap of ``identify``'s intervals: refits of synthetic recordings.

The Jacobian's interval assumes residuals that are the sensor noise alone;
quantisation of a slow signal and a drive loop's response to its noisy
sensors break that. :func:`bootstrap` re-simulates the fit as the truth with
the recorded sensor model, refits each synthetic recording, and widens every
interval to the spread of those refits.
"""
import dataclasses

import numpy as np

from . import fit as ident
from .data import REL_MAX, t_quantile
from ...core.params import ScrewParams


#: Synthetic recordings of the parametric bootstrap of the intervals, and how far from the
#: fitted values (in half-widths of their intervals) each refit starts.
BOOTSTRAP, AWAY = 4, 2.0


def bootstrap(problem, res, names, start, coords, max_nfev, bounds):
    """
    Widen each interval to the spread of refits of synthetic recordings (a parametric bootstrap).

    Each of :data:`BOOTSTRAP` synthetic recordings re-simulates the commands at
    the fitted values with the recorded sensor model and its own seed (not the
    recording's), so it holds what the recording would hold if the fit were
    the truth: sensor noise, quantisation, and in velocity and position mode
    that noise acting on the motion through the drive. Each is fitted the
    same way from the fitted values; the RMS of their errors delta_j about
    those values is the estimator's error s_b, which the Jacobian's interval
    misses where the residuals are not the noise it assumes (quantisation
    of a slow signal, the loop's response to its sensors). The interval
    becomes value +- max(w, t_K s_b) (t quantile of K degrees of freedom: the
    errors' mean is known to be 0). Returns the new FitResult.

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
    errors, nfev = _refit_errors(problem, res, names, start, coords, max_nfev, bounds)
    s_b = np.sqrt(np.mean(np.array(errors) ** 2, axis=0))
    tq = t_975(BOOTSTRAP)
    verdicts, lower, upper = [], [], []
    for i, (v, vd, c) in enumerate(zip(res.values, res.verdicts, coords)):
        problem.bootstrap[c.name] = float(s_b[i])
        if vd.identified and tq * s_b[i] > 0.5 * (vd.upper - vd.lower):
            vd = _widened(vd, v, c, tq * float(s_b[i]), float(s_b[i]))
        verdicts.append(vd)
        lower.append(vd.lower)
        upper.append(vd.upper)
    values = [v if vd.identified else v0
              for v, v0, vd in zip(res.values, res.initial, verdicts)]
    return dataclasses.replace(res, values=values, lower=lower, upper=upper,
                               verdicts=verdicts, nfev=nfev)


def _refit_errors(problem, res, names, start, coords, max_nfev, bounds):
    """
    Return the errors of the refits of the synthetic recordings and the fit's nfev with theirs.

    The arguments are :func:`bootstrap`'s.
    """
    fitted = dict(zip(res.names, res.values))
    sensors = {n: getattr(problem.recorded, n) for n in ident.IDEAL_SENSORS}
    meas = problem.measurements
    recorded = (meas.data, meas.mask, problem.anchoring)
    errors, nfev = [], res.nfev
    try:
        for j in range(BOOTSTRAP):
            sensors['sensor_seed'] = (problem.recorded.sensor_seed + 1 + j) % 2 ** 31
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
                step = AWAY * 0.5 * (vd.upper - vd.lower) if vd.identified else 0.0
                away[c.name] = min(c.upper, max(c.lower, v + sign * step))
            syn = ident.fit(problem.residuals, ident.coordinates(
                names, ScrewParams.from_dict(away, base=start), bounds),
                max_nfev=max_nfev, rounds=1, scan=False, jac_steps=problem.jac_steps)
            errors.append(np.array(syn.values) - np.array(res.values))
            nfev += syn.nfev
    finally:
        meas.data, meas.mask, problem.anchoring = recorded
    return errors, nfev


def _widened(vd, v, c, hw, s_b):
    """Return the verdict of value ``v`` of coordinate ``c`` with the half-width ``hw``."""
    lo, hi = max(c.lower, v - hw), min(c.upper, v + hw)
    rel = 0.5 * (hi - lo) / max(abs(v), c.typical)
    ok = rel <= REL_MAX
    why = (f'identified: 95 % interval +-{100 * rel:.3g} % (the spread of {BOOTSTRAP} '
           'refits of synthetic recordings)' if ok else
           f'not identifiable: refits of {BOOTSTRAP} synthetic recordings spread '
           f'+-{100 * rel:.3g} %: the noise, not the data, decides it')
    return dataclasses.replace(vd, identified=ok, reason=why, lower=lo, upper=hi, rel=rel,
                               std=s_b)


def t_975(dof):
    """Return the 97.5 % quantile of the t distribution of ``dof`` degrees of freedom."""
    return t_quantile(0.95, dof)
