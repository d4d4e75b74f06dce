"""
Verdicts conditional on what is held: refits with a held parameter across its plausible range.

A fitted parameter judged not identifiable keeps its starting value, a
guess; the others were fitted with it there, and their intervals assume it
is right. :func:`conditional` refits the recording with each held parameter
at its start and at the ends of its plausible range (its fitting bounds, or
+-:data:`PLAUSIBLE` of the start where that is narrower), the others free. A
parameter the refits move by more than its own interval gets its interval
widened by its largest move on both sides (or, past the bar of
:data:`.data.REL_MAX`, the verdict not identifiable), so that no interval
misses the truth because a neighbour was guessed; every fitted parameter's
reason then says that it is conditional on the held one ("conditional on
mu_s held at 0.2").

Both sides, because three refits only sample how the value depends on the
held parameter: where that is not monotone, the truth lies between the
samples on the side neither end moved it to. On the breakaway ramps
(``bench/bench_coverage.py``, seeds 7 and 19) the Stribeck velocity is held
at its start, 1 mm/s; refits with it at 0.5 and 1.5 mm/s moved mu_k by
+0 % and +0.42 %, while with it at the truth, 1.15 mm/s, mu_k is 0.02 %
below the fit at 1 mm/s, where its interval (+-0.0011 %, the noise's)
excluded the truth.
"""
import dataclasses
import math

from . import fit as ident
from .data import REL_MAX
from ...core.params import ScrewParams

#: Half-width of a held parameter's plausible range [share of its start] where its bounds
#: are wider; a start of 0 takes its typical size.
PLAUSIBLE = 0.5

#: Relative move of an exact-data value (no interval) across a held parameter's range below
#: which it stays "exact data"; above it the value is conditional, and past REL_MAX it is
#: not identifiable.
EXACT_MOVE = 1e-6


def plausible_range(c):
    """Return the plausible (low, high) values [unit] of a held coordinate ``c``."""
    size = abs(c.initial) or c.typical
    return max(c.lower, c.initial - PLAUSIBLE * size), min(c.upper, c.initial + PLAUSIBLE * size)


def conditional(residuals, res, coords, start, *, max_nfev=None, jac_steps=None, exact=False):
    """
    Return ``res`` with its verdicts conditional on the parameters it holds at their start.

    Parameters
    ----------
    residuals : callable
        The fit's ``residuals(values, n)`` (:func:`.fit.fit`).
    res : FitResult
        The fit (after its bootstrap, if any).
    coords : list of Coordinate
        The fitted parameters' coordinates (their bounds).
    start : ScrewParams
        The starting and fixed values.
    max_nfev : int, optional
        Most re-simulations per refit.
    jac_steps : tuple, optional
        The intervals' Jacobian steps of the problem.
    exact : bool
        Exact data.

    Returns
    -------
    (FitResult, list of str)
        The fit with the widened intervals and verdicts, and one line per
        held parameter saying what its refits moved.

    """
    free = [i for i, vd in enumerate(res.verdicts) if vd.fitted]
    held = [i for i, vd in enumerate(res.verdicts) if not vd.fitted]
    if not free or not held:
        return res, []
    names = [res.names[i] for i in free]
    bounds = {c.name: (c.lower, c.upper) for c in coords}
    values, verdicts, notes, nfev = list(res.values), list(res.verdicts), [], res.nfev
    for h in held:
        c = coords[h]
        ends = plausible_range(c)
        runs = []
        for v_held in (c.initial,) + tuple(ends):
            base = ScrewParams.from_dict({**dict(zip(res.names, values)), c.name: v_held},
                                         base=start)
            refit = ident.fit(residuals, ident.coordinates(names, base, bounds),
                              fixed={c.name: v_held}, max_nfev=max_nfev, rounds=1, scan=False,
                              jac_steps=jac_steps or ident.INTERVAL_JAC_STEPS, exact=exact)
            nfev += refit.nfev
            runs.append(refit.values)
        # the moves from the reported values: the refit at the start too (the others may
        # have been fitted with the held one elsewhere before its verdict held it)
        moves = {n: [run[k] - values[free[k]] for run in runs] for k, n in enumerate(names)}
        said = []
        for k, i in enumerate(free):
            vd, v = verdicts[i], values[i]
            lo_move, hi_move = min(moves[names[k]] + [0.0]), max(moves[names[k]] + [0.0])
            size = max(abs(v), coords[i].typical)
            rel_move = max(abs(lo_move), abs(hi_move)) / size
            cond = (f'conditional on {c.name} held at {c.initial:.6g} (refits with it at '
                    f'{ends[0]:.6g} and {ends[1]:.6g} move it by {100 * lo_move / size:+.3g} % '
                    f'and {100 * hi_move / size:+.3g} %)')
            said.append(f'{names[k]} {100 * lo_move / size:+.3g} % / '
                        f'{100 * hi_move / size:+.3g} %')
            verdicts[i] = _conditioned(vd, v, lo_move, hi_move, size, rel_move, cond)
        notes.append(f'conditional on {c.name} held at {c.initial:.6g}: refits with it at '
                     f'{ends[0]:.6g} and {ends[1]:.6g} moved ' + ', '.join(said))
    lower = [vd.lower if vd.identified else math.nan for vd in verdicts]
    upper = [vd.upper if vd.identified else math.nan for vd in verdicts]
    values = [v if vd.fitted else v0 for v, v0, vd in zip(values, res.initial, verdicts)]
    return dataclasses.replace(res, values=values, verdicts=verdicts, lower=lower, upper=upper,
                               nfev=nfev), notes


def _conditioned(vd, v, lo_move, hi_move, size, rel_move, cond):
    """Return verdict ``vd`` of value ``v`` widened by its largest move and said conditional."""
    if vd.identified:
        move = max(-lo_move, hi_move)
        lower, upper = min(vd.lower, v - move), max(vd.upper, v + move)
        rel = 0.5 * (upper - lower) / size
        if rel > REL_MAX:
            return dataclasses.replace(vd, identified=False, lower=lower, upper=upper, rel=rel,
                                       reason=f'not identifiable: {cond}, past the bar of '
                                       f'+-{100 * REL_MAX:g} %')
        widened = lower < vd.lower or upper > vd.upper
        head = (f'identified: 95 % interval +-{100 * rel:.3g} %, widened by the largest move '
                'on both sides' if widened else vd.reason)
        return dataclasses.replace(vd, lower=lower, upper=upper, rel=rel,
                                   reason=f'{head}; {cond}')
    if vd.exact:
        if rel_move > REL_MAX:
            return dataclasses.replace(vd, exact=False, rel=math.inf,
                                       reason=f'not identifiable: {cond}, past the bar of '
                                       f'+-{100 * REL_MAX:g} %')
        if rel_move > EXACT_MOVE:
            return dataclasses.replace(vd, reason=f'{vd.reason}; {cond}')
    return vd
