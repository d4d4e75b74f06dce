"""
``identify``: fit parameters so that re-simulating a recording's commands gives its states.

The recorded commands go through the model (:class:`.replay.Resim`, the
node's command rules) with ideal sensors; the residuals are the simulated
less the recorded sensor signals (encoder angle, scale position, and the
motor torque unless every command is a torque command), each divided by its
noise level. :mod:`leadscrew_sim.analysis.identify.fit` fits them; the report,
the parameter file and the plot come from :mod:`.identify_report`. Starting
and fixed values come from ``--preset`` / ``--params`` / ``--set`` (by
default the preset the recording names), never from the recording's
parameters: those would be the answer.
"""
import dataclasses
import math
import time

import numpy as np

from . import identify_report as R
from ..offline.options import keep_freed_memory, NS, RunError
from ..analysis.identify.bootstrap import bootstrap
from ..analysis.identify import fit as ident
from ..analysis.identify import steps as fit_steps
from ..core.engine.drive import MODE_TORQUE
from ..core.params import ParameterError, ScrewParams
from ..io.mcap_reader import Recording
from ..io.run_file import PARAMS_RECORD

HELP = 'fit friction, backlash and other parameters to a recording'

#: The recording's measurement setup: taken from its parameters record, never fitted.
SETUP_FIELDS = tuple(n for n in ScrewParams.names()
                     if n.startswith(('encoder_', 'scale_', 'fault_'))) + (
    'linear_scale', 'velocity_filter_time', 'sensor_seed', 'state_delay', 'command_delay')


def add_arguments(p):
    """Add the options of ``identify`` to parser ``p``."""
    p.add_argument('file', help='the recording (MCAP)')
    p.add_argument('--fit', help=f'comma list of parameters to fit (default '
                   f'{",".join(ident.DEFAULT_FIT)}; fittable: {", ".join(ident.FITTABLE)})')
    p.add_argument('--preset', help='starting and fixed values: a preset (default: the one '
                   'the recording names, else tr12x3)')
    p.add_argument('--params', help='starting and fixed values: a ROS 2 parameter file')
    p.add_argument('--set', action='append', metavar='NAME=VALUE',
                   help='a starting or fixed value (repeatable)')
    p.add_argument('--output-params', metavar='FILE.yaml', help='write the fitted set as a '
                   'parameter file (simulate --params, the node)')
    p.add_argument('--report', metavar='FILE', help='also write the report (it is printed)')
    p.add_argument('--plot', metavar='FILE.png', help='recorded, initial and fitted signals')
    p.add_argument('--state-topic', help='JointState topic of the measured states '
                   '(a foreign recording; default joint_states)')
    p.add_argument('--command-topic', help='command topic (a foreign recording)')
    p.add_argument('--command-kind', choices=('torque', 'velocity', 'position'),
                   help='what a Float64 command on --command-topic is: motor torque [N m], '
                   'nut velocity [m/s] or nut position [m]')
    p.add_argument('--screw-joint', help='joint name of the screw (motor) in the states')
    p.add_argument('--nut-joint', help='joint name of the nut in the states')
    p.add_argument('--rate', type=float, help='step rate [Hz] of a foreign recording '
                   '(default 1000)')
    p.add_argument('--max-nfev', type=int, help='most re-simulations per fit stage')
    p.add_argument('--restarts', choices=('auto', 'on', 'off'), default='auto',
                   help='restart the re-simulation from the recorded state at each rest of '
                   'a torque-mode recording and compare only the steps that state '
                   'determines (auto: when one run from the start does not explain the '
                   'recording; on: always; off: never)')
    p.add_argument('--quiet', '-q', action='store_true', help='do not print the report')


class Problem:
    """
    A recording set up for fitting: its replay, its measured signals and their weights.

    ``replay(values)`` returns the columns of ``model.run`` of every step with
    the starting set, ``values`` and ideal sensors; ``measurements`` the
    recorded sensor signals on the same step grid.
    """

    def __init__(self, args, rec, start):
        """Read the recording (a leadscrew_sim one, or foreign with the mapping options)."""
        foreign = bool(args.state_topic or args.command_topic) or \
            rec.record(PARAMS_RECORD) is None
        self.start = start
        if foreign:
            src = R.ForeignReplay(args, rec, start)
            recorded = start
        else:
            from ..offline.replay import Resim
            src = Resim(rec)
            recorded = src.params
            R.check_geometry(start, recorded)
        self.source, self.foreign, self.recorded = src, foreign, recorded
        self.dt = src.dt_ns / NS
        _segments, commands, _forces = src.inputs()
        modes = commands[:, 0][np.isfinite(commands[:, 0])]
        if not len(modes) or src.n_steps == 0:
            raise RunError(f'{rec.path}: no drive commands (torque_command, velocity_command, '
                           'position_command or joint_commands) to re-simulate')
        self.torque_only = bool(np.all(modes == MODE_TORQUE))
        self.mode_names = sorted({('torque', 'velocity', 'position', 'quick_stop')[int(m)]
                                  for m in np.unique(modes)})
        setup = {n: getattr(recorded, n) for n in SETUP_FIELDS}
        base = {n: getattr(start, n) for n in ScrewParams.names() if n not in SETUP_FIELDS}
        self.overrides = {**base, **setup, **ident.noiseless_sensors(
            ScrewParams.from_dict(dict(encoder_bias=ident.NULL_BIAS), base=recorded)
            if foreign else recorded)}
        data = src.measured() if foreign else R.measured_of_resim(src)
        self.measurements, self.noise = R.measurements(rec.path, data, recorded,
                                                       self.torque_only, foreign)
        self.n = src.n_steps
        self.slow = 0
        if not (self.torque_only or foreign) and recorded.encoder_counts > 0:
            self.slow = fit_steps.drop_slow(self.measurements, commands, recorded, self.dt)
        self.commands, self.forces = commands, _forces
        self.anchoring = None
        self.restartable = self.torque_only and not foreign and len(_segments) == 1 and \
            not _segments[0].events
        self.sigma0 = dict(self.measurements.sigma)
        if args.restarts == 'on':
            self.restart()
        self.evaluations = 0
        self.raised = []
        self.loop_noise = {}
        if not (self.torque_only or foreign) and ident.sensor_sigma(recorded) != \
                ident.sensor_sigma(ScrewParams()):
            self._add_loop_noise(recorded)

    def _add_loop_noise(self, recorded):
        """
        Add to each signal's noise level the spread the sensor noise causes through the drive.

        In velocity and position mode the drive closes its loops over the noisy,
        quantised sensors, so the recorded motion itself carries their noise
        (the motor follows the noise within the loop's bandwidth); the
        noiseless re-simulation cannot have it. Its size is measured by one
        re-simulation at the starting values with the recorded sensor model
        (another seed, so not the recorded noise) against the noiseless one:
        the RMS difference of each signal, offset removed, is added in
        quadrature to the sensor's own level.
        """
        sensors = {n: getattr(recorded, n) for n in ident.IDEAL_SENSORS}
        sensors['sensor_seed'] = (recorded.sensor_seed + 1) % 2 ** 31
        noisy = self.replay(sensors)
        clean = self.replay({})
        meas = self.measurements
        for name in meas.names:
            col = {'screw_angle': 'motor_angle'}.get(name, name)
            d = np.asarray(noisy[col][:self.n]) - np.asarray(clean[col][:self.n])
            if name in ident.OFFSET_SIGNALS:
                d = d - d.mean()
            loop = float(np.sqrt(np.mean(d ** 2)))
            self.loop_noise[name] = loop
            sigma, how = self.noise[name]
            total = math.hypot(sigma, loop) if how == 'sensor parameters' else max(sigma, loop)
            meas.sigma[name] = total
            self.noise[name] = (total, f'{how} and the drive loop\'s response to the '
                                f'sensor noise ({loop:.3g})')

    @property
    def jac_steps(self):
        """Return the relative steps of the intervals' Jacobian (wider with restarts)."""
        return ident.JAC_STEPS if self.anchoring is None else fit_steps.JAC_STEPS

    def restart(self):
        """
        Restart the re-simulation at the recording's rests, if it has any; return whether.

        The signals' weights return to their noise levels (a fit in one run may
        have raised them).
        """
        meas = self.measurements
        raised = meas.sigma
        meas.sigma = dict(self.sigma0)
        if not self.restartable or fit_steps.anchoring_of(meas, self.commands, self.dt) is None:
            meas.sigma = raised
            return False
        self.raised = []
        self.use_data(meas.data, {})
        return True

    def use_data(self, data, values):
        """
        Compare with measured ``data`` (n_signals, n) from now on.

        With restarts the rests are found in ``data`` and the steps compared are
        those the rests determine at the physical ``values`` (:mod:`.fit_steps`).
        """
        meas = self.measurements
        if not hasattr(self, 'base_mask'):
            self.base_mask = meas.mask.copy()
        meas.data, meas.mask = data, self.base_mask.copy()
        self.anchoring = fit_steps.anchoring_of(meas, self.commands, self.dt)
        if self.anchoring is not None:
            self.predict(values)

    def predict(self, values):
        """Compare only the steps the rests determine at ``values``; return whether they moved."""
        meas = self.measurements
        overrides = dict(self.overrides, **values)
        keep = self.anchoring.predictable(lambda: self.source.model(overrides), self.commands,
                                          self.forces, [(meas.columns[s], meas.sigma[s])
                                                        for s in meas.names])
        mask = self.base_mask & keep[None, :meas.n]
        changed = not np.array_equal(mask, meas.mask)
        meas.mask = mask
        return changed

    def replay(self, values, n=None, plain=False):
        """
        Return the re-simulated columns of the first ``n`` steps (all: None) with ``values``.

        Restarted at the rests unless ``plain`` (one run from the start, as recorded).
        """
        self.evaluations += 1
        overrides = dict(self.overrides, **values)
        try:
            if self.anchoring is not None and not plain:
                return self.anchoring.run(self.source.model(overrides), self.commands,
                                          self.forces, n)
            if n is None or self.foreign:
                return self.source.replay(overrides, n) if self.foreign else \
                    self.source.replay(overrides)
            src = self.source          # the steps up to n only: the horizon of a fit stage
            parts, done = [], 0
            for part, cols in src.blocks(src.model(overrides), overrides=overrides,
                                         block_ticks=n):
                parts.append(cols)
                done = part.k1
                if done >= n:
                    break
            return {k: np.concatenate([c[k] for c in parts]) for k in parts[0]} if parts \
                else {}
        except ParameterError as exc:
            raise RunError(f're-simulation with {values}: {exc}') from None

    def compared(self, cols):
        """Return the columns ``cols`` of a re-simulation at the steps some signal is compared."""
        used = self.measurements.mask.any(axis=0)
        return {k: np.asarray(v)[:len(used)][used[:len(v)]] for k, v in cols.items()}

    def residuals(self, values, n=None):
        """Return the weighted residuals of the first ``n`` steps (all: None)."""
        return self.measurements.residuals(self.replay(values, n), n)


def hints(cols):
    """Return name -> why this run cannot show the parameter, from a re-simulation's columns."""
    out = {}
    contact = np.asarray(cols['contact'])
    if len(np.unique(contact[contact != 0])) < 2:
        out['backlash'] = 'the thread contact never changed flank (no load reversal)'
    stick = np.asarray(cols['stick_a'])
    breaks = np.count_nonzero((stick[:-1] == 1) & (stick[1:] == 0))
    if breaks == 0:
        out['mu_s'] = 'the thread never broke away from standstill'
    slide = np.abs(np.asarray(cols['sliding_velocity']))
    if slide.max(initial=0.0) == 0.0:
        out['mu_k'] = out['stribeck_velocity'] = out['mu_viscous'] = 'the thread never slid'
    return out


def horizons(problem):
    """Return the growing fit horizons [steps]: n / 16 (at least 200 steps) .. n / 2."""
    n, hs = problem.n, []
    h = n // 2
    while h >= max(200, n // 16):
        hs.insert(0, h)
        h //= 2
    return hs or None


def fit_recording(args):
    """
    Fit the parameters of ``args`` to its recording; return the pieces of the outputs.

    Returns
    -------
    dict
        res (FitResult), params (the fitted ScrewParams), problem, label,
        initial and final (the re-simulated columns), wall [s], single (the
        rejected FitResult of one run from the start when restarts at the
        rests replaced it, else None), second (None without a second attempt,
        else whether it explained the recording).

    """
    names = R.fit_names(args.fit)
    if args.rate is not None and not (math.isfinite(args.rate) and 1.0 <= args.rate <= 1e6):
        raise RunError(f'--rate {args.rate} Hz must lie in [1, 1e6]')
    t_wall = time.perf_counter()
    rec = Recording(args.file)
    rec.require_ros2()
    start, label = R.start_params(args, rec)
    problem = Problem(args, rec, start)
    try:
        coords = ident.coordinates(names, start)
    except ValueError as exc:
        raise RunError(f'--fit: {exc}') from None
    weights = dict(problem.measurements.sigma)
    res, initial, final, misfit = _fit(problem, coords, names, start, args)
    single = None           # the fit in one run, when it missed and restarts replaced it
    if misfit and args.restarts == 'auto' and problem.restart():
        single = _reject(res, misfit)
        res, initial, final, misfit = _fit(problem, coords, names, start, args)
        res.nfev += single.nfev
    second = None           # whether a second attempt explained the recording (None: none)
    if misfit and problem.anchoring is None:
        res, initial, final, misfit = _rescanned(problem, coords, names, start, args, weights,
                                                 (res, initial, final, misfit))
        second = not misfit
    problem.bootstrap = {}
    if misfit:
        res = _reject(res, misfit)
        final = problem.replay(dict(zip(res.names, res.values)))
    elif not problem.foreign and ident.sensor_sigma(problem.recorded) != \
            ident.sensor_sigma(ScrewParams()):
        res = bootstrap(problem, res, names, start, coords, args, _bounds(coords))
        final = problem.replay(dict(zip(res.names, res.values)))
    params = ScrewParams.from_dict({n: v for n, v, vd in zip(res.names, res.values,
                                                             res.verdicts) if vd.identified},
                                   base=start)
    return dict(res=res, params=params, problem=problem, label=label, initial=initial,
                final=final, wall=time.perf_counter() - t_wall, single=single, second=second)


#: Most refits after the steps compared moved with the fitted values (restarts at rests).
PREDICT_ROUNDS = 3


def _fit(problem, coords, names, start, args, rescan=False):
    """
    Fit ``problem`` from ``start``; return (FitResult, initial and final columns, misfit).

    With restarts at rests the steps compared are those the rests determine at
    the fitted values, and the fit is repeated while they change; a signal
    the model explains only to an RMS above its noise is then weighted by
    that RMS and the fit repeated. ``misfit``: why the fit does not explain
    the recording ('' when it does).
    """
    initial = problem.replay({})
    why = hints(problem.compared(initial))
    res = ident.fit(problem.residuals, coords, horizons=horizons(problem), hints=why,
                    max_nfev=args.max_nfev, profile=problem.anchoring is not None,
                    rescan=rescan, jac_steps=problem.jac_steps)
    fitted = dict(zip(res.names, res.values))
    for _again in range(PREDICT_ROUNDS):    # the steps the rests determine at the fit
        if problem.anchoring is None or not problem.predict(fitted):
            break
        res = _refit(problem, res, names, start, coords, args, why)
        fitted = dict(zip(res.names, res.values))
    final = problem.replay(fitted)
    problem.raised = problem.measurements.reweight(final)
    if problem.raised:              # refit with those signals' weights at their rms
        res = _refit(problem, res, names, start, coords, args, why)
        final = problem.replay(dict(zip(res.names, res.values)))
    return res, initial, final, _misfit(problem, final)


def _rescanned(problem, coords, names, start, args, weights, missed):
    """
    Fit once more with the later stages' scans also from the start; return the better fit.

    ``missed`` is the fit (as :func:`_fit` returns it) that does not explain the
    recording; the new one starts with the signals' weights ``weights`` of the
    first and replaces it only if it explains the recording. Either way the
    re-simulations of both are counted.
    """
    kept = (dict(problem.measurements.sigma), list(problem.raised))
    problem.measurements.sigma, problem.raised = dict(weights), []
    again = _fit(problem, coords, names, start, args, rescan=True)
    nfev = missed[0].nfev + again[0].nfev
    if again[3]:
        problem.measurements.sigma, problem.raised = kept
        again = missed
    again[0].nfev = nfev
    return again


def _refit(problem, res, names, start, coords, args, why):
    """Return the fit of ``problem`` again from the values of ``res`` (its nfev added)."""
    again = ScrewParams.from_dict(dict(zip(res.names, res.values)), base=start)
    res2 = ident.fit(problem.residuals, ident.coordinates(names, again, _bounds(coords)),
                     hints=why, max_nfev=args.max_nfev, jac_steps=problem.jac_steps)
    res2.initial, res2.nfev = res.initial, res.nfev + res2.nfev
    return res2


def run(args):
    """Fit the parameters and write the report, the parameter file and the plot."""
    keep_freed_memory()                 # thousands of re-simulations reuse their blocks
    out = fit_recording(args)
    text = R.report(args.file, out)
    if not args.quiet:
        print(text)
    if args.report:
        R.write_text(args.report, text + '\n', '--report')
    if args.output_params:
        R.write_params(args.output_params, out['params'], out['label'], out['res'])
    if args.plot:
        R.plot(args.plot, out['problem'], out['initial'], out['final'])
    return 0


#: Largest residual RMS / noise level of a signal at an accepted fit: a fit of the right
#: minimum leaves about 1 (the tests' accepted fits stay below 2).
MISFIT = 2.5


def _misfit(problem, final):
    """Return why the fit does not explain the recording ('' when it does)."""
    meas = problem.measurements
    bad = [f'{name} {rms / problem.noise[name][0]:.3g}' for name, rms in
           zip(meas.names, meas.rms(final)) if rms > MISFIT * problem.noise[name][0]]
    if not bad:
        return ''
    return (f'the fit does not explain the recording (RMS / sigma: {", ".join(bad)}; above '
            f'{MISFIT:g} the re-simulation stopped in a wrong minimum or lacks something)')


def _reject(res, why):
    """Return ``res`` with every parameter not identifiable for ``why``, at its start."""
    verdicts = [dataclasses.replace(vd, identified=False, reason=f'not identifiable: {why}')
                for vd in res.verdicts]
    nan = [float('nan')] * len(res.names)
    return dataclasses.replace(res, values=list(res.initial), verdicts=verdicts, lower=nan,
                               upper=list(nan))


def _bounds(coords):
    """Return name -> (lower, upper) of coordinates (a refit keeps the first fit's bounds)."""
    return {c.name: (c.lower, c.upper) for c in coords}
