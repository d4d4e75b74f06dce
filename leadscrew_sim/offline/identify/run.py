"""
The fit of ``identify``: parameters whose re-simulation of a recording's commands gives its states.

The recording becomes a :class:`.problem.Problem`: its commands
re-simulated with ideal sensors, the residuals the simulated less the
recorded sensor signals, each divided by its noise level;
:mod:`leadscrew_sim.analysis.identify.fit` fits them. A fit that does not
explain the recording is repeated with restarts at the recording's rests
(a torque-mode recording), else once more with its later scans also from
the start, then from the start with every fitted parameter 10 % up and
10 % down (:data:`SHIFT`); an explained fit's intervals are widened by the parametric
bootstrap when the sensors are noisy. Starting and fixed values come from
``preset`` / ``params`` / ``set`` (by default the preset the
recording names), never from the recording's parameters: those would be
the answer.
"""
import dataclasses
import math
import time

import numpy as np

from .inputs import fit_names, FLOOR, start_params
from .problem import Problem
from ..options import open_recording, RunError
from ...analysis.identify.bootstrap import bootstrap
from ...analysis.identify.conditional import conditional
from ...analysis.identify.degeneracy import motion_degeneracies, static_episodes
from ...analysis.identify import fit as ident
from ...core.params import ScrewParams


def horizons(problem):
    """Return the growing fit horizons [steps]: n / 16 (at least 200 steps) .. n / 2."""
    n, hs = problem.n, []
    h = n // 2
    while h >= max(200, n // 16):
        hs.insert(0, h)
        h //= 2
    return hs or None


def fit_recording(args, progress=None):
    """
    Fit the parameters of ``args`` to its recording; return the pieces of the outputs.

    Parameters
    ----------
    args : argparse.Namespace
        The options of ``leadscrew_sim identify`` (the recording ``file``,
        ``fit``, the starting values, a foreign recording's mapping,
        ``rate`` [Hz], ``max_nfev``, ``restarts``).
    progress : FitProgress, optional
        The status line on a terminal (:mod:`.progress`).

    Returns
    -------
    dict
        res (FitResult), params (the fitted ScrewParams), problem, label,
        initial and final (the re-simulated columns), wall [s], single (the
        rejected FitResult of one run from the start when restarts at the
        rests replaced it, else None), second (None without a second attempt,
        else whether it explained the recording), shifted, loop_at_fit and
        on_compared (the later attempts: None when not made, else what they
        tried and whether it explained the recording).

    """
    names = fit_names(args.fit)
    if args.rate is not None and not (math.isfinite(args.rate) and 1.0 <= args.rate <= 1e6):
        raise RunError(f'<<step_rate>> {args.rate} Hz must lie in [1, 1e6]')
    t_wall = time.perf_counter()
    rec = open_recording(args.file)
    rec.require_ros2()
    start, label = start_params(args, rec)
    problem = Problem(args, rec, start)
    problem.progress = progress
    try:
        coords = ident.coordinates(names, start)
    except ValueError as exc:
        raise RunError(f'<<fit>>: {exc}') from None
    problem.resolve_floor(coords)
    problem.judged = _compared_levels(problem)
    plan = Plan(problem, names, start, coords, args.max_nfev)
    weights = dict(problem.measurements.sigma)
    res, initial, final, misfit = _fit(plan)
    problem.unexplained = _noise_like(problem, final) if misfit else []
    if problem.unexplained:     # no other minimum explains noise: fail fast, name the signal
        misfit = _unexplained_why(problem)
    single = None           # the fit in one run, when it missed and restarts replaced it
    if misfit and not problem.unexplained and args.restarts == 'auto' and problem.restart():
        single = _reject(res, misfit)
        problem.stage = 'fit with restarts at the rests'
        res, initial, final, misfit = _fit(plan)
        res.nfev += single.nfev
    second = None           # whether a second attempt explained the recording (None: none)
    if misfit and problem.anchoring is None and not problem.unexplained:
        problem.stage = 'second fit'
        res, initial, final, misfit = _rescanned(plan, weights, (res, initial, final, misfit))
        second = not misfit
    shifted = None          # the shifted starts tried, and whether one explained the recording
    if misfit and problem.anchoring is None and not problem.unexplained:
        problem.stage = 'fit from shifted starts'
        (res, initial, final, misfit), shifted = _shifted(plan, weights,
                                                          (res, initial, final, misfit))
    loop_at_fit = None      # the signals whose loop response grew at the fit, explained
    if misfit and problem.anchoring is None and not problem.unexplained:
        problem.stage = 'fit with the drive loop\'s response measured at the fit'
        (res, initial, final, misfit), loop_at_fit = _loop_at_fit(
            plan, weights, (res, initial, final, misfit))
    on_compared = None      # the signals whose level fell over the steps compared, explained
    if misfit and problem.anchoring is None and not problem.unexplained and problem.slow:
        problem.stage = 'fit with the drive loop\'s response over the steps compared'
        (res, initial, final, misfit), on_compared = _loop_on_compared(
            plan, weights, (res, initial, final, misfit))
    problem.bootstrap, problem.resolution = {}, {}
    if misfit:      # final stays the rejected fit's: the report's RMS is the verdict's
        res = _reject(res, misfit)
    elif any(problem.loop_sensors[n] for n in ('encoder_counts', 'encoder_noise',
                                               'scale_resolution', 'scale_noise')):
        problem.stage = 'bootstrap of the intervals'
        res = bootstrap(problem, res, names, start, coords, args.max_nfev, plan.bounds)
        final = problem.replay(dict(zip(res.names, res.values)))
    problem.conditions = []
    if not misfit:
        problem.stage = 'refits with the held parameters across their range'
        res, problem.conditions = conditional(problem.residuals, res, coords, start,
                                              max_nfev=args.max_nfev,
                                              jac_steps=problem.jac_steps, exact=problem.exact)
        if problem.conditions:
            final = problem.replay(dict(zip(res.names, res.values)))
    params = ScrewParams.from_dict({n: v for n, v, vd in zip(res.names, res.values,
                                                             res.verdicts) if vd.fitted},
                                   base=start)
    return dict(res=res, params=params, problem=problem, label=label, initial=initial,
                final=final, wall=time.perf_counter() - t_wall, single=single, second=second,
                shifted=shifted, loop_at_fit=loop_at_fit, on_compared=on_compared)


@dataclasses.dataclass(frozen=True)
class Plan:
    """
    What every fit of a recording shares: the problem, the fitted names, the start, the bounds.

    ``coords`` are the fitted parameters' coordinates at ``start`` (their
    bounds hold for every refit); ``max_nfev`` the most re-simulations per
    fit stage (None: 50 per parameter).
    """

    problem: Problem
    names: list
    start: ScrewParams
    coords: list
    max_nfev: int

    @property
    def bounds(self):
        """Return name -> (lower, upper) of the coordinates (a refit keeps the first's)."""
        return {c.name: (c.lower, c.upper) for c in self.coords}


#: Most refits after the steps compared moved with the fitted values (restarts at rests).
PREDICT_ROUNDS = 3


def _fit(plan, rescan=False):
    """
    Fit the plan's problem from its start; return (FitResult, initial and final columns, misfit).

    With restarts at rests the steps compared are those the rests determine at
    the fitted values, and the fit is repeated while they change; so it is
    when the motion's degeneracies (:mod:`..analysis.identify.degeneracy`) at the
    fit differ from those at the start; a signal
    the model explains only to an RMS above its noise is then weighted by
    that RMS and the fit repeated. ``misfit``: why the fit does not explain
    the recording ('' when it does).
    """
    problem = plan.problem
    initial = problem.replay({})
    why = _degeneracies(plan, problem.compared(initial), {})
    res = ident.fit(problem.residuals, plan.coords, horizons=horizons(problem), hints=why,
                    max_nfev=plan.max_nfev, profile=problem.anchoring is not None,
                    valley=True, rescan=rescan, jac_steps=problem.jac_steps, exact=problem.exact)
    fitted = dict(zip(res.names, res.values))
    for _again in range(PREDICT_ROUNDS):    # the steps the rests determine at the fit
        if problem.anchoring is None or not problem.predict(fitted):
            break
        res = _refit(plan, res, why)
        fitted = dict(zip(res.names, res.values))
    final = problem.replay(fitted)
    seen = _degeneracies(plan, problem.compared(final), fitted)
    if set(seen) != set(why):       # the motion at the fit shows other events than at the start
        why = seen
        res = _refit(plan, res, why)
        final = problem.replay(dict(zip(res.names, res.values)))
    problem.raised = problem.measurements.reweight(final)
    if problem.raised:              # refit with those signals' weights at their rms
        res = _refit(plan, res, why)
        final = problem.replay(dict(zip(res.names, res.values)))
    return res, initial, final, _misfit(problem, final)


def _degeneracies(plan, cols, values):
    """
    Return :func:`motion_degeneracies` of compared columns ``cols`` at the physical ``values``.

    The friction curve (Stribeck velocity and exponent) is the one of
    ``values`` over the start; the episodes in which the static friction acts
    (their first and last times [s]) are kept in ``problem.static``.
    """
    curve = tuple(values.get(n, getattr(plan.start, n))
                  for n in ('stribeck_velocity', 'stribeck_exponent'))
    t = np.asarray(cols['time'], dtype=float)
    plan.problem.static = [(float(t[a]), float(t[b])) for a, b in static_episodes(cols, curve)]
    return motion_degeneracies(cols, curve)


def _rescanned(plan, weights, missed):
    """
    Fit once more with the later stages' scans also from the start; return the better fit.

    ``missed`` is the fit (as :func:`_fit` returns it) that does not explain the
    recording; the new one starts with the signals' weights ``weights`` of the
    first and replaces it only if it explains the recording. Either way the
    re-simulations of both are counted.
    """
    problem = plan.problem
    kept = (dict(problem.measurements.sigma), list(problem.raised))
    problem.measurements.sigma, problem.raised = dict(weights), []
    again = _fit(plan, rescan=True)
    nfev = missed[0].nfev + again[0].nfev
    if again[3]:
        problem.measurements.sigma, problem.raised = kept
        again = missed
    again[0].nfev = nfev
    return again


#: Relative move of every fitted parameter's start in the last attempts (up, then down): a
#: start can lie in a basin that neither the horizons nor the scans leave, while one a
#: tenth away does not (friction fitted from a preset's mu_k 15 % above the axis's).
SHIFT = 0.1


def _shifted(plan, weights, missed):
    """
    Fit from the start, every fitted parameter moved by +-SHIFT; return the fit and the tries.

    ``missed`` is the fit (as :func:`_fit` returns it) that does not explain
    the recording after the second attempt. Each shifted start is fitted as
    the first was (the signals' weights ``weights`` of the first); the first
    that explains the recording replaces ``missed``. Returns (fit, (tries,
    explained)); the re-simulations of every attempt are counted and the
    start reported stays the plan's.
    """
    problem = plan.problem
    kept = (dict(problem.measurements.sigma), list(problem.raised))
    nfev = missed[0].nfev
    for tries, sign in enumerate((1.0, -1.0), start=1):
        moved = {c.name: min(c.upper, max(c.lower, c.initial * (1.0 + sign * SHIFT)))
                 for c in plan.coords}
        start = ScrewParams.from_dict(moved, base=plan.start)
        alt = dataclasses.replace(plan, start=start,
                                  coords=ident.coordinates(plan.names, start, plan.bounds))
        problem.measurements.sigma, problem.raised = dict(weights), []
        again = _fit(alt)
        nfev += again[0].nfev
        if not again[3]:
            again[0].nfev, again[0].initial = nfev, missed[0].initial
            return again, (tries, True)
    problem.measurements.sigma, problem.raised = kept
    missed[0].nfev = nfev
    return missed, (tries, False)


#: Growth of a signal's noise level, measured again at a rejected fit, that makes the fit
#: worth repeating with it. The drive loop's response to its sensors depends on the speeds
#: and the friction: over a noise-free 17-bit encoder, tr12x3's sweep moves the motor by
#: 4.3e-6 rad RMS at the preset's friction and by 6.7e-5 rad at an axis's (mu_s 0.23, mu_k
#: 0.13), so the level measured at the start can be far too small to weigh the screw angle.
LOOP_GROWTH = 1.5


def _loop_at_fit(plan, weights, missed):
    """
    Measure the drive loop's response at the rejected fit; fit again where it grew.

    ``missed`` is the fit (as :func:`_fit` returns it) that no attempt made
    explain the recording; ``weights`` the signals' noise levels of the
    first fit. The loop's response to the sensors
    (:meth:`Problem.add_loop_noise`) is measured again at its values; if a
    signal's level grows by more than :data:`LOOP_GROWTH`, the recording is
    fitted again from the start with those levels (:func:`_with_levels`).
    """
    return _with_levels(plan, missed, dict(zip(missed[0].names, missed[0].values)), False,
                        lambda new, old: new > LOOP_GROWTH * old, weights,
                        'measured at the first fit')


#: Factor by which a signal's noise level over the steps compared must fall below the first
#: fit's for a fit with those levels: the steps left out (a slow level's limit cycle) differ
#: most between the loop's runs, and on a commission run over DDS (17-bit encoder, 1 um
#: scale) they made the motor angle's level 8.8e-5 rad against 8.6e-6 rad over the rest.
LOOP_FALL = 1.5


def _loop_on_compared(plan, weights, missed):
    """
    Measure the drive loop's response over the steps compared; fit again where it fell.

    The last attempt, for a recording with steps left out
    (:func:`...analysis.identify.steps.drop_slow`): ``missed`` and
    ``weights`` as :func:`_loop_at_fit`'s. The loop's response at the start
    is measured again over the steps the residuals compare; if a signal's
    level falls by more than :data:`LOOP_FALL`, the recording is fitted
    again from the start with those levels and judged against them, a
    stricter bar (:func:`_with_levels`).
    """
    return _with_levels(plan, missed, {}, True, lambda new, old: LOOP_FALL * new < old,
                        weights, 'over the steps compared')


def _with_levels(plan, missed, values, compared, changed, weights, note):
    """
    Fit again from the start with the loop's response measured anew, if a level changed.

    The response is measured at the physical ``values`` (over the steps
    compared when ``compared``); the signals whose new level ``changed(new,
    weights[name])`` are those it changed. The new fit replaces ``missed``
    if it explains the recording, and those signals' levels say ``note``;
    else the levels are restored. Returns (fit, None when no level changed,
    else (the signals whose level changed, whether the new fit explained the
    recording)).
    """
    problem = plan.problem
    if not problem.loop_noise:
        return missed, None
    meas = problem.measurements
    kept = (dict(meas.sigma), dict(problem.noise), dict(problem.loop_noise),
            list(problem.raised))
    problem.add_loop_noise(values, compared=compared)
    moved = [n for n in meas.names if changed(meas.sigma[n], weights[n])]
    if not moved:
        meas.sigma, problem.noise, problem.loop_noise, problem.raised = kept
        return missed, None
    problem.raised = []
    again = _fit(plan)
    again[0].nfev += missed[0].nfev
    if again[3]:
        meas.sigma, problem.noise, problem.loop_noise, problem.raised = kept
        missed[0].nfev = again[0].nfev
        return missed, (moved, False)
    for n in meas.names:
        sigma, how = problem.noise[n]
        problem.noise[n] = (sigma, f'{how}, {note}' if n in moved else how)
    return again, (moved, True)


def _refit(plan, res, why):
    """Return the fit of the plan's problem again from the values of ``res`` (its nfev added)."""
    again = ScrewParams.from_dict(dict(zip(res.names, res.values)), base=plan.start)
    res2 = ident.fit(plan.problem.residuals, ident.coordinates(plan.names, again, plan.bounds),
                     hints=why, max_nfev=plan.max_nfev, valley=True,
                     jac_steps=plan.problem.jac_steps, exact=plan.problem.exact)
    res2.initial, res2.nfev = res.initial, res.nfev + res2.nfev
    return res2


#: Largest residual RMS / noise level of a signal at an accepted fit: a fit of the right
#: minimum leaves about 1 (the tests' accepted fits stay below 2).
MISFIT = 2.5


def _misfit(problem, final):
    """
    Return why the fit does not explain the recording ('' when it does).

    Each signal's RMS is judged against its noise level, or against its level
    over the steps compared (``problem.judged``) where that is lower.
    """
    meas = problem.measurements
    levels = {n: min(problem.noise[n][0], problem.judged.get(n, math.inf))
              for n in meas.names}
    bad = [f'{name} {rms / levels[name]:.3g}' for name, rms in
           zip(meas.names, meas.rms(final)) if rms > MISFIT * levels[name]]
    if not bad:
        return ''
    over = (', each against its level over the steps compared where that is lower'
            if any(levels[n] < problem.noise[n][0] for n in meas.names) else '')
    return (f'the fit does not explain the recording (RMS / sigma: {", ".join(bad)}{over}; '
            f'above {MISFIT:g} the re-simulation stopped in a wrong minimum or lacks '
            'something)')


def _compared_levels(problem):
    """
    Return name -> the noise level with the loop's response over the steps compared only.

    Only for a recording with steps left out (:func:`...analysis.identify.steps.drop_slow`)
    whose levels hold the loop's response: those steps' limit cycles differ most between
    two runs of the loop, and counted they raise a level (tenfold for the motor angle of
    a commission run over DDS), so that a fit in the wrong valley of mu_s and the Stribeck
    velocity passed the bar. The fit's weights keep the levels of all steps.
    """
    if not (problem.slow and problem.loop_noise):
        return {}
    meas = problem.measurements
    kept = (dict(meas.sigma), dict(problem.noise), dict(problem.loop_noise))
    problem.add_loop_noise({}, compared=True)
    judged = {n: problem.noise[n][0] for n in meas.names}
    meas.sigma, problem.noise, problem.loop_noise = kept
    return judged


#: Least step-to-step spread of a signal's residual at a rejected fit, in units of its noise
#: level, that says the noise level, not the minimum, is wrong: a re-simulation is smooth
#: from step to step, so no parameter set adds or removes that spread, and another search
#: would not explain it either.
NOISE_LIKE = MISFIT


def _white_spread(d):
    """
    Return the white-noise level [unit] of a residual ``d`` from its fourth differences.

    sqrt(mean(d4^2) / 70): the fourth difference of white noise has the
    variance 70 sigma^2, while a smooth misfit's (a friction error's drift)
    is far below it; a quantiser's staircase counts as the noise it is.
    """
    d4 = np.diff(np.asarray(d, dtype=float), 4)
    return float(np.sqrt(np.mean(d4 ** 2) / 70.0)) if len(d4) else 0.0


def _noise_like(problem, final):
    """
    Return [(signal, spread [unit])] whose residual at ``final`` is noise above its level.

    Only a signal whose level is the numerical floor while the others' are
    not (data that are not exact): a level from known sensors is trusted,
    and a wrong minimum of a chaotic re-simulation (stick_slip's ringing
    coupling) has a rough residual too, which a second search may explain.
    Not on exact data: there every level is the floor, and a wrong minimum's
    breakaways a step off are spikes far above it.
    """
    meas = problem.measurements
    if problem.exact:
        return []
    d = meas.differences(final)
    out = []
    for i, name in enumerate(meas.names):
        if not problem.noise[name][1].startswith(FLOOR):
            continue
        m = meas.mask[i]
        w = _white_spread(d[i][m])
        if w > NOISE_LIKE * problem.noise[name][0]:
            out.append((name, w))
    return out


def _unexplained_why(problem):
    """Return the rejection of a fit whose signals carry noise above their levels."""
    parts = []
    for name, w in problem.unexplained:
        sigma, how = problem.noise[name]
        parts.append(f'{name} is not explained: its residual\'s step-to-step spread '
                     f'{w:.3g} {problem.measurements.units[name]} is {w / sigma:.3g} times '
                     f'its noise level ({how})')
    return ('the fit does not explain the recording (' + '; '.join(parts) + '; no '
            'parameter set of a re-simulation adds such noise: give the sensor\'s resolution '
            'and noise, e.g. <<set>> scale_resolution=..., <<set>> scale_noise=...)')


def _reject(res, why):
    """Return ``res`` with every parameter not identifiable for ``why``, at its start."""
    verdicts = [dataclasses.replace(vd, identified=False, exact=False,
                                    reason=f'not identifiable: {why}')
                for vd in res.verdicts]
    nan = [float('nan')] * len(res.names)
    return dataclasses.replace(res, values=list(res.initial), verdicts=verdicts, lower=nan,
                               upper=list(nan))
