"""
Parameter identification: bounded nonlinear least squares on a re-simulation (no ROS, no I/O).

The caller supplies ``residuals(values) -> array (n_signals, n_time)``: the
re-simulation of the recorded commands with the physical values ``{name:
value}``, less the measured signals, divided by each signal's noise level
(:class:`.data.Measurements`). :func:`fit` minimises the sum of squares with
a bounded trust-region reflective method (:func:`.lsq.least_squares`,
scipy's ``'trf'`` on arithmetic no BLAS kernel changes) in scaled
coordinates (:class:`Coordinate`: z = v / s, or z = ln(v / s) for a parameter
that spans decades), then estimates the covariance from the final Jacobian,
95 % intervals (t distribution), the correlations, and a verdict per
parameter (:mod:`.data`).

The covariance is the sandwich B M B with B = (J^T J)^-1 and M the
long-run covariance of the per-step scores g_t = sum_s J_st r_st (Bartlett
weights, bandwidth by Andrews' AR(1) plug-in rule). For white residuals M
equals s^2 J^T J and the sandwich is the textbook s^2 (J^T J)^-1; the
residuals of a re-simulation are serially correlated (quantisation of a
slow signal, a drive loop's response to its sensor noise), and the plain
formula would give intervals that are too narrow.
"""
import dataclasses
import math
import time

import numpy as np

from ...core.params import ScrewParams
from . import data as V
from . import linalg as la
from .search import (local_fit, profiled, restart_fit, scanned, SCAN_ABOVE, valley_scan,
                     SearchOptions, spread)
from .data import (Coordinate, IDEAL_SENSORS, Measurements,
                   noiseless_sensors, NULL_BIAS, OFFSET_SIGNALS, sandwich, scaled_inverse,
                   sensor_sigma, SIGNALS)
from .noise import noise_estimate

__all__ = ['Coordinate', 'DEFAULT_FIT', 'FitResult', 'FITTABLE', 'IDEAL_SENSORS', 'LEVEL',
           'Measurements', 'NULL_BIAS', 'OFFSET_SIGNALS', 'SIGNALS', 'bounds', 'coordinates',
           'fit', 'noise_estimate', 'noiseless_sensors', 'sandwich', 'scaled_inverse',
           'sensor_sigma', 'typical_size']

#: Parameters ``identify`` fits when not told otherwise.
DEFAULT_FIT = ('mu_s', 'mu_k', 'stribeck_velocity', 'mu_viscous', 'backlash',
               'bearing_coulomb', 'guide_coulomb')

#: Fittable parameter -> (log coordinates, typical size): the typical size scales a
#: parameter whose starting value is 0 and is the yardstick of a zero-valued one's interval.
FITTABLE = {
    'mu_s': (False, 0.05), 'mu_k': (False, 0.05), 'stribeck_velocity': (True, 1e-4),
    'stribeck_exponent': (False, 1.0), 'mu_viscous': (False, 1.0),
    'backlash': (False, 1e-5), 'bearing_coulomb': (False, 'torque'),
    'bearing_viscous': (False, 'torque_rate'), 'guide_coulomb': (False, 'force'),
    'guide_viscous': (False, 'force_rate'), 'motor_inertia': (True, 1e-6),
    'screw_inertia': (True, 1e-6), 'payload_mass': (False, 1.0), 'nut_mass': (True, 0.01),
    'preload_force': (False, 1.0), 'contact_damping': (True, 100.0),
}

#: Two-sided confidence level of the intervals.
LEVEL = 0.95


def typical_size(name, params):
    """
    Return the typical size of a fittable parameter (its unit) for the axis ``params``.

    Torque-like sizes are 1 % of ``max_torque``; force-like ones that torque
    through the lead (F = 2 pi T / l); rate-like ones per 10 rad/s or 10 mm/s.

    Parameters
    ----------
    name : str
        A key of :data:`FITTABLE`.
    params : ScrewParams
        The axis.

    """
    size = FITTABLE[name][1]
    torque = 0.01 * params.max_torque
    force = torque * 2.0 * math.pi / params.lead
    return {'torque': torque, 'torque_rate': torque / 10.0, 'force': force,
            'force_rate': force / 0.01}.get(size, size)


def bounds(name, params):
    """
    Return the physical (lower, upper) limits of a fitted parameter of an axis.

    The field's range (:meth:`ScrewParams.field_info`), tightened to physical
    sense: thread friction below the jam limit mu' tan(lambda) < 1 (at 90 %)
    and below 1; the backlash below half the pitch; the Stribeck velocity in
    [1e-6, 1] m/s; the backlash also below 10 times its start (or 0.1 mm);
    inertias and masses within a factor 100 of the start; the
    Coulomb terms below the motor's torque; |mu_viscous| <= 10 s/m.

    Parameters
    ----------
    name : str
        A key of :data:`FITTABLE`.
    params : ScrewParams
        The starting set.

    """
    md = ScrewParams.field_info()[name][2]
    lo, hi = md['lo'], md['hi']
    v = getattr(params, name)
    torque_force = params.max_torque * 2.0 * math.pi / params.lead
    tight = {
        'mu_s': (0.0, min(1.0, 0.9 / (params.thread_factor * math.tan(params.lead_angle)))),
        'mu_k': (0.0, min(1.0, 0.9 / (params.thread_factor * math.tan(params.lead_angle)))),
        'stribeck_velocity': (1e-6, 1.0), 'stribeck_exponent': (0.3, 5.0),
        'mu_viscous': (-10.0, 10.0),
        'backlash': (0.0, min(0.5 * params.pitch, max(10.0 * v, 1e-4))),
        'bearing_coulomb': (0.0, 0.5 * params.max_torque),
        'bearing_viscous': (0.0, params.max_torque / 10.0),
        'guide_coulomb': (0.0, 0.5 * torque_force), 'guide_viscous': (0.0, torque_force / 0.01),
        'payload_mass': (0.0, max(100.0 * v, 1.0)), 'preload_force': (0.0, max(10.0 * v, 10.0)),
    }
    if FITTABLE[name][0]:
        a, b = tight.get(name, (v / 100.0, v * 100.0))
    else:
        a, b = tight.get(name, (lo, hi))
    return max(a, lo) if lo is not None else a, min(b, hi) if hi is not None else b


def coordinates(names, params, fixed_bounds=None):
    """
    Return the :class:`Coordinate` of each parameter in ``names``, starting at ``params``.

    Parameters
    ----------
    names : sequence of str
        Keys of :data:`FITTABLE`.
    params : ScrewParams
        Starting values (and the axis the bounds derive from).
    fixed_bounds : dict, optional
        name -> (lower, upper) replacing :func:`bounds`.

    """
    out = []
    for name in names:
        if name not in FITTABLE:
            raise ValueError(f'{name!r} is not a fittable parameter (fittable: '
                             f'{", ".join(FITTABLE)})')
        lo, hi = (fixed_bounds or {}).get(name) or bounds(name, params)
        v0 = float(getattr(params, name))
        log, _size = FITTABLE[name]
        typ = typical_size(name, params)
        if not lo <= v0 <= hi:
            raise ValueError(f'starting value {name}={v0!r} lies outside its fitting bounds '
                             f'[{lo!r}, {hi!r}]')
        if log and v0 <= 0.0:
            raise ValueError(f'starting value {name}={v0!r} must be > 0')
        scale = v0 if log else (abs(v0) if v0 != 0.0 else typ)
        out.append(Coordinate(name, v0, lo, hi, log, scale, typ))
    return out


@dataclasses.dataclass
class FitResult:
    """
    What :func:`fit` found: values, intervals, correlations, verdicts and its cost.

    Parameters
    ----------
    names : list of str
        The fitted parameters.
    initial, values : list of float
        Their start and end values [their units].
    lower, upper : list of float
        The 95 % interval of each [their units] (NaN where none).
    std : list of float
        The standard error of each [their units].
    correlation : numpy.ndarray
        Their correlation matrix.
    verdicts : list of Verdict
        Identified or not, and why, for each.
    rms : numpy.ndarray
        The residual RMS of each signal, in noise units.
    n_residuals, dof : int
        Residuals compared, and their degrees of freedom.
    bandwidth : int
        Correlation length of the residuals [samples].
    nfev : int
        Re-simulations made.
    wall : float
        Wall time [s].
    message : str
        The optimiser's last message.
    singular_values : numpy.ndarray, optional
        Of the weighted Jacobian at the end.
    rms_initial : numpy.ndarray, optional
        The residual RMS at the start.

    """

    names: list
    initial: list
    values: list
    lower: list
    upper: list
    std: list
    correlation: np.ndarray
    verdicts: list
    rms: np.ndarray
    n_residuals: int
    dof: int
    bandwidth: int
    nfev: int
    wall: float
    message: str
    singular_values: np.ndarray = None
    rms_initial: np.ndarray = None

    def value(self, name):
        """
        Return the value of parameter ``name`` (fitted, or kept at its start).

        Parameters
        ----------
        name : str
            A fitted parameter.

        """
        return self.values[self.names.index(name)]

    def verdict(self, name):
        """
        Return the :class:`~.data.Verdict` of parameter ``name``.

        Parameters
        ----------
        name : str
            A fitted parameter.

        """
        return self.verdicts[self.names.index(name)]


class _Counted:
    """The residual function in z coordinates, flattened, counting its calls."""

    def __init__(self, residuals, coords, fixed):
        self.residuals, self.coords, self.fixed = residuals, coords, fixed
        self.nfev = 0
        self.shape, self.size = None, 0
        self.horizon = None

    def values(self, z):
        vals = dict(self.fixed)
        vals.update({c.name: c.to_value(zi) for c, zi in zip(self.coords, z)})
        return vals

    def __call__(self, z):
        self.nfev += 1
        r = np.asarray(self.residuals(self.values(z), self.horizon), dtype=float)
        self.shape, self.size = r.shape, r.size
        return r.ravel()


#: Relative steps of the Jacobian of the intervals, and the factor by which the growing
#: horizons' stages widen the optimiser's steps.
INTERVAL_JAC_STEPS, COARSE = (1e-5, 1e-3), 10.0


class _Anchored:
    """
    The residuals of a horizon stage with a weak pull toward the stage's start.

    A short horizon may not see a parameter at all (the backlash before the
    first reversal, the Stribeck velocity before the first slow plateau); the
    extra residuals (z - z_start) / :data:`ANCHOR` keep such a parameter where
    it was instead of letting it wander to a bound. Where the data see a
    parameter their weight (residuals in noise units over many samples)
    overrides the pull; the whole run's stage has none.
    """

    def __init__(self, fun, z0):
        self.fun, self.z0 = fun, np.array(z0, dtype=float)

    def __call__(self, z):
        return np.concatenate([self.fun(z), (z - self.z0) / ANCHOR])


#: Width of the pull of a horizon stage toward its start, in z units (about 100 %).
ANCHOR = 1.0


def fit(residuals, coords, fixed=None, *, horizons=None, diff_step=1e-3, max_nfev=None,
        hints=None, ftol=1e-8, xtol=1e-8, rounds=2, scan=True, rescan=False, profile=False,
        valley=False, jac_steps=INTERVAL_JAC_STEPS, exact=False):
    """
    Fit parameters so that ``residuals`` shrinks; return a :class:`FitResult`.

    A parameter whose verdict is not identifiable (exact data: free) keeps its
    starting value and is fixed there; the others are fitted again without it
    (at most ``rounds`` fits).

    Parameters
    ----------
    residuals : callable
        ``residuals(values, n) -> array (n_signals, n)``: the weighted residuals
        (in noise units, 0 where nothing was measured) of the first n steps (all
        when n is None), values ``{name: value}`` in SI units.
    coords : list of Coordinate
        The fitted parameters (:func:`coordinates`).
    fixed : dict, optional
        Values handed to ``residuals`` with every call besides the fitted ones.
    horizons : list of int, optional
        Growing horizons [steps] fitted one after the other, each from the last
        one's solution, before the whole run: the error of a simulation grows
        with time, so a long run seen at once from a distant start has many
        local minima; a short one has few. The first stage also starts from
        each log-scaled parameter divided and multiplied by :data:`SPREAD`
        and keeps the best.
    diff_step : float
        Relative step of the optimiser's finite-difference Jacobian in z
        coordinates (:data:`COARSE` times larger in the horizon stages: a wide
        step averages over the jumps of a piecewise smooth re-simulation).
    max_nfev : int, optional
        Most re-simulations per fit (default 50 per parameter).
    hints : dict, optional
        name -> a sentence on why the data lacks what that parameter needs,
        appended to a verdict of no sensitivity.
    ftol, xtol : float
        Tolerances of the local fits.
    rounds : int
        Most fits.
    scan : bool
        Scan coordinate by coordinate out of a stage that leaves a residual
        above twice the noise (False: local fits only).
    rescan : bool
        Also start the scans of the later stages from the starting point: a
        short horizon can favour a basin that the longer ones then cannot leave.
    profile : bool
        Also scan each log-scaled parameter's profile after the whole run's
        stage (:func:`profiled`).
    valley : bool
        Also scan along the cost's principal axes after the whole run's stage
        (:func:`valley_scan`): a narrow, rough valley that the local fits stall in.
    jac_steps : tuple of float
        Relative steps in z of the intervals' Jacobian (:func:`.data.interval_jacobian`).
    exact : bool
        Exact data (weights at the numerical floor): no intervals (:func:`.data.judge`).

    """
    t_wall = time.perf_counter()
    fixed, active, start = dict(fixed or {}), list(coords), {c.name: c.initial for c in coords}
    held = {}                    # name -> Verdict of the parameters fixed at their start
    nfev, message, rms0 = 0, '', None
    for _round in range(rounds):
        fun = _Counted(residuals, active, dict(fixed, **{n: start[n] for n in held}))
        z0 = np.array([c.to_z(c.initial) for c in active])
        if rms0 is None:
            rms0 = _rms(fun(z0), fun.shape)      # fun(z0) sets fun.shape
        if not active:
            r, jac, z = fun(z0), np.zeros((fun(z0).size, 0)), z0
            break
        opts = _search_options(active, diff_step, ftol, xtol, max_nfev)
        first = _round == 0
        res, z = _stages(fun, active, z0, opts, horizons if first else None, scan and first,
                         rescan, (profile and first, valley and first))
        r, jac, verdicts, counted = _judged(fun, active, z, opts, jac_steps, hints, exact)
        nfev, message = nfev + counted, res.message
        if all(v.fitted for v in verdicts) or _round == rounds - 1:
            break
        held.update({c.name: v for c, v in zip(active, verdicts) if not v.fitted})
        active = [dataclasses.replace(c, initial=c.to_value(zi))    # from where they were
                  for c, zi, v in zip(active, z, verdicts) if v.fitted]
    return _result(coords, active, z, jac, r, fun, held, (nfev, t_wall, message, rms0),
                   hints, exact)


def _search_options(coords, diff_step, ftol, xtol, max_nfev):
    """Return the SearchOptions of a round: the bounds of ``coords`` in z and the options."""
    lo = np.array([c.to_z(c.lower) if not (c.log and c.lower <= 0) else -np.inf
                   for c in coords])
    hi = np.array([c.to_z(c.upper) for c in coords])
    return SearchOptions(lo, hi, diff_step, ftol, xtol, max_nfev, len(coords))


def _stages(fun, coords, z0, opts, horizons, scan, rescan, after):
    """
    Fit the ``horizons`` stages (None: none) and the whole run; return (result, its z).

    ``opts`` are those of the whole run's stage; the horizon stages fit the
    residuals pulled toward their start (:class:`_Anchored`) with a
    :data:`COARSE` step, the first of them also from the :func:`spread`
    points. ``scan`` and ``rescan`` as :func:`fit`'s; ``after`` (profile, valley)
    the searches of the whole run's stage, as :func:`fit`'s ``profile`` and ``valley``.
    """
    z = np.clip(z0, opts.lo, opts.hi)
    for stage, h in enumerate((horizons or []) + [None]):
        fun.horizon = h
        starts = [z] + (spread(z, coords, opts.lo, opts.hi) if h is not None else [])
        step = opts.replace(diff_step=opts.diff_step * (COARSE if h is not None else 1.0))
        target = fun if h is None else _Anchored(fun, z)
        best = None
        for zs in starts:
            res = local_fit(target, zs, step)
            if best is None or res.cost < best.cost:
                best = res
        res = best
        if h is None:
            res, _z = restart_fit(fun, res, opts)
        if scan and np.max(_rms(res.fun[:fun.size], fun.shape)) > SCAN_ABOVE:
            origins = [z, res.x] + ([z0] if rescan and stage > 0 else [])
            res = scanned(target, res, origins, coords, step, restart=h is None)
        if h is None and after[0]:
            res = profiled(fun, res, coords, opts)
        if h is None and after[1]:
            res = valley_scan(fun, res, opts)
        z = res.x
    return res, z


def _judged(fun, coords, z, opts, jac_steps, hints, exact):
    """
    Return the whole run's residuals at ``z``, the intervals' Jacobian, the verdicts and nfev.

    The count is of the evaluations outside the Jacobian's.
    """
    fun.horizon = None
    r = fun(z)
    counted = fun.nfev
    jac = V.interval_jacobian(fun, z, r, jac_steps, opts.lo, opts.hi)
    nfev_after = fun.nfev
    cov, _lag = sandwich(jac, r, fun.shape)
    verdicts = V.judge(coords, z, jac, cov, r, opts.lo, opts.hi, LEVEL,
                       dof=_dof(r, len(coords)), hints=hints, exact=exact)
    counted += fun.nfev - nfev_after
    return r, jac, verdicts, counted


def _dof(r, p):
    """Return the degrees of freedom of the residuals: measured values less parameters."""
    return max(1, int(np.count_nonzero(r)) - p)


def _rms(r, shape):
    """Return the RMS of each signal's residuals (over its measured samples)."""
    m = r.reshape(shape)
    n = np.maximum(1, np.count_nonzero(m, axis=1))
    return np.sqrt((m ** 2).sum(axis=1) / n)


def _result(coords, active, z, jac, r, fun, held, run, hints, exact):
    """Assemble the FitResult of the last fit, with the held parameters at their start."""
    nfev, t_wall, message, rms0 = run
    cov, lag = (sandwich(jac, r, fun.shape) if active else (np.zeros((0, 0)), 0))
    dof = _dof(r, len(active))
    verdicts = V.judge(active, z, jac, cov, r, None, None, LEVEL, dof=dof, hints=hints,
                       exact=exact) if active else []
    final = {c.name: (c, zi, v, i) for i, (c, zi, v) in enumerate(zip(active, z, verdicts))}
    names, values, lower, upper, std, out_verdicts, idx = [], [], [], [], [], [], []
    for c in coords:
        names.append(c.name)
        if c.name in final:
            ca, zi, v, i = final[c.name]
            values.append(ca.to_value(zi))
            lower.append(v.lower)
            upper.append(v.upper)
            std.append(v.std)
            out_verdicts.append(v)
            idx.append(i)
        else:
            values.append(c.initial)
            lower.append(math.nan)
            upper.append(math.nan)
            std.append(math.nan)
            out_verdicts.append(held[c.name])
            idx.append(None)
    corr = np.full((len(coords), len(coords)), np.nan)
    if active:
        d = np.sqrt(np.maximum(np.diag(cov), 1e-300))
        with np.errstate(invalid='ignore'):     # inf / inf: a column without sensitivity
            c_act = cov / np.outer(d, d)
        for a, ia in enumerate(idx):
            for b, ib in enumerate(idx):
                if ia is not None and ib is not None:
                    corr[a, b] = c_act[ia, ib]
    sv = la.singular_values(la.unit_columns(jac)[0]) if active else np.zeros(0)
    return FitResult(names=names, initial=[c.initial for c in coords], values=values,
                     lower=lower, upper=upper, std=std, correlation=corr,
                     verdicts=out_verdicts, rms=_rms(r, fun.shape), n_residuals=int(r.size),
                     dof=dof, bandwidth=lag, nfev=nfev, wall=time.perf_counter() - t_wall,
                     message=message, singular_values=sv, rms_initial=rms0)
