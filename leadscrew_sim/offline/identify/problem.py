"""
The problem ``identify`` fits: a recording's replay, its measured signals and their weights.

The recorded commands go through the model (:class:`..replay.resim.Resim`, the
node's command rules; a foreign recording through
:class:`.inputs.ForeignReplay`) with ideal sensors; the measured
signals are the encoder angle, the scale position, and the motor torque
unless every command is a torque command, each weighted by its noise level.
"""
import math

import numpy as np

from .inputs import (check_geometry, data_sensors, ESTIMATED, FLOOR, ForeignReplay,
                     measured_of_resim, measurements)
from .progress import rms_per_signal
from ..foreign.delay import Delay
from ..foreign.replay import hermite, SLOPES
from ..options import NS, RunError
from ..replay.resim import Resim
from ...analysis.identify import fit as ident
from ...analysis.identify import steps as fit_steps
from ...core.drive_modes import MODE_TORQUE
from ...core.params import ParameterError, ScrewParams
from ...io.run_file import PARAMS_RECORD

#: The recording's measurement setup: taken from its parameters record, never fitted.
SETUP_FIELDS = tuple(n for n in ScrewParams.names()
                     if n.startswith(('encoder_', 'scale_', 'fault_'))) + (
    'linear_scale', 'velocity_filter_time', 'sensor_seed', 'state_delay', 'command_delay')

#: Relative parameter change below which exact data count a fit as the truth (its floor).
RESOLUTION = 1e-6

#: Least and largest range [s] either side of a foreign recording's estimated
#: command-to-state delay within which each re-simulation is aligned to the states (three
#: half-widths of the estimate, and at least as far as no delay and SHIFT_MIN beyond).
SHIFT_MIN, SHIFT_MAX = 2e-3, 1e-2

#: Trial shifts of each of the alignment's grids, and how many grids, each about the best
#: of the one before and spanning two of its intervals.
SHIFT_GRID, SHIFT_ROUNDS = 9, 2
#: Most recorded states the alignment's search compares (evenly taken).
SHIFT_STATES = 300

#: Seeds of the re-simulations that measure the drive loop's response to the sensor noise.
LOOP_SEEDS = 1


class Problem:
    """
    A recording set up for fitting: its replay, its measured signals and their weights.

    ``replay(values)`` returns the columns of ``model.run`` of every step with
    the starting set, ``values`` and ideal sensors; ``measurements`` the
    recorded sensor signals on the same step grid.
    """

    def __init__(self, args, rec, start):
        """
        Read the recording (a leadscrew_sim one, or foreign with the mapping options).

        A foreign recording's command-to-state delay is the mapping's, else
        estimated with ``start`` and fitted with the parameters (:meth:`_aligned`).
        """
        foreign = bool(args.state_topic or args.command_topic) or \
            rec.record(PARAMS_RECORD) is None
        self.start = start
        if foreign:
            src = ForeignReplay(args, rec, start, estimate_delay=True)
            if src.delay.how == 'estimated' and not src.delay.half_width <= SHIFT_MAX:
                # with the starting values far from the axis's the estimate can be anywhere
                # (a falling axis gave -41 +- 365 ms): the search starts from no delay
                d = src.delay
                src.set_delay(Delay(0.0, d.half_width, 'uncertain', d.signal, d.value))
            recorded = start
        else:
            src = Resim(rec)
            recorded = src.params
            check_geometry(start, recorded)
        self.source, self.foreign, self.recorded = src, foreign, recorded
        # a foreign recording's delay, unless the mapping sets it, is fitted with the
        # parameters: each re-simulation is aligned in time to the states (:meth:`_aligned`)
        self.fit_delay = foreign and src.delay.how != 'set'
        half = src.delay.half_width if foreign and src.delay.how == 'estimated' else math.nan
        # the range also reaches no delay: an estimate made with friction far off is biased
        # by the twin's other lag, by as much as itself (test_identify's tr12x3 speed
        # ladder stripped of its record: -3.8 +- 0.66 ms estimated, 0 true)
        self.shift_range = min(SHIFT_MAX, max(SHIFT_MIN, 3.0 * half,
                                              abs(src.delay.value) + SHIFT_MIN)) \
            if math.isfinite(half) else SHIFT_MAX
        self.shift_ns = 0
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
        data = src.measured() if foreign else measured_of_resim(src)
        self.measurements, self.noise = measurements(
            rec.path, data, recorded, self.torque_only, foreign,
            src.sample_times() if foreign else None)
        # exact data: every signal's noise level is the numerical floor (ideal sensors)
        self.exact = all(how == FLOOR for _s, how in self.noise.values())
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
        # the progress on a terminal (FitProgress, None: none), what is fitted, the last misfit
        self.progress, self.stage, self.misfit = None, 'fit', {}
        self.raised = []
        self.loop_noise = {}
        # name -> the level the misfit bar uses where lower than the noise level (run.py)
        self.judged = {}
        # the sensors the drive loop closed over: the recording's, else those the starting
        # set declares or the data show (a foreign recording)
        self.loop_sensors = {n: getattr(recorded, n) for n in ident.IDEAL_SENSORS}
        if foreign:
            self.loop_sensors.update(data_sensors(recorded, data, self.noise))
        if not self.torque_only and any(
                self.loop_sensors[n] for n in ('encoder_counts', 'encoder_noise',
                                               'scale_resolution', 'scale_noise')):
            self.sensor_noise = dict(self.noise)
            self.add_loop_noise({})

    def add_loop_noise(self, values, compared=False):
        """
        Add to each signal's noise level the spread the sensor noise causes through the drive.

        In velocity and position mode the drive closes its loops over the noisy,
        quantised sensors, so the recorded motion itself carries their noise
        (the motor follows the noise within the loop's bandwidth); the
        noiseless re-simulation cannot have it. Its size is measured by
        :data:`LOOP_SEEDS` re-simulations at the physical ``values`` (the
        start's) with the recorded sensor model (other seeds, so not the
        recorded noise) against the noiseless one: the RMS difference of each
        signal, offset removed, over all of them, is added in quadrature to the
        sensor's own level. The spread is heavy-tailed (a 16-bit encoder at one
        speed gave 1.3e-5, 1.9e-4 and 1.5e-5 rad with three seeds), but more
        seeds, or a measurement again at the fit, change the weights of the
        tested fits and lose three of them (stick_slip's ladders, the split
        nut's second attempt): one seed, as those were tuned with. ``compared``:
        the RMS over the steps the residuals compare only (the steps left out,
        a slow level's limit cycle, differ most between the runs).
        """
        recorded = self.recorded
        sensors = dict(self.loop_sensors)
        clean = self.replay(values, plain=True)
        noisy = []
        for j in range(LOOP_SEEDS):
            sensors['sensor_seed'] = (recorded.sensor_seed + 1 + j) % 2 ** 31
            noisy.append(self.replay(dict(values, **sensors), plain=True))
        meas = self.measurements
        for i, name in enumerate(meas.names):
            col = {'screw_angle': 'motor_angle'}.get(name, name)
            d = np.array([np.asarray(run[col][:self.n]) - np.asarray(clean[col][:self.n])
                          for run in noisy])
            if compared and meas.mask[i, :self.n].any():
                d = d[:, meas.mask[i, :self.n]]
            if name in ident.OFFSET_SIGNALS:
                d = d - d.mean(axis=1, keepdims=True)
            loop = float(np.sqrt(np.mean(d ** 2)))
            self.loop_noise[name] = loop
            sigma, how = self.sensor_noise[name]
            total = max(sigma, loop) if how.startswith(ESTIMATED) else math.hypot(sigma, loop)
            meas.sigma[name] = total
            self.noise[name] = (total, f'{how} and the drive loop\'s response to the '
                                f'sensor noise ({loop:.3g})')

    def resolve_floor(self, coords):
        """
        Raise exact data's numerical floor to what the fit can resolve of ``coords``.

        A noise-free recording's residual at the truth is 0, but a fit stops at
        its tolerance, and a re-simulation changes in jumps (a breakaway a step
        earlier) below it: a floor of 1e-9 of a signal's range is out of reach
        of the right answer (the clean sweep's fit ends at 6 times it) and
        turns it into a rejection. The floor of each signal becomes at least
        the RMS change (offsets removed, the steps compared) of a
        re-simulation at the start when every fitted parameter moves by
        :data:`RESOLUTION` of itself (its typical size when 0), summed in
        quadrature: values closer than that to the truth count as exact.
        """
        if not self.exact or not coords:
            return
        meas = self.measurements
        base = meas.differences(self.replay({}))
        total = np.zeros(len(meas.names))
        for c in coords:
            v = c.initial + RESOLUTION * (abs(c.initial) or c.typical)
            d = meas.differences(self.replay({c.name: v})) - base
            total += (d ** 2).sum(axis=1) / np.maximum(1, meas.mask.sum(axis=1))
        for name, change in zip(meas.names, np.sqrt(total)):
            if change > meas.sigma[name]:
                meas.sigma[name] = float(change)
                self.noise[name] = (float(change), FLOOR)
        self.sigma0 = dict(meas.sigma)

    @property
    def jac_steps(self):
        """Return the relative steps of the intervals' Jacobian (wider with restarts)."""
        return (ident.INTERVAL_JAC_STEPS if self.anchoring is None
                else fit_steps.RESTART_JAC_STEPS)

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
        those the rests determine at the physical ``values``
        (:mod:`leadscrew_sim.analysis.identify.steps`).
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

    def replay(self, values, n=None, plain=False, lean=False):
        """
        Return the re-simulated columns of the first ``n`` steps (all: None) with ``values``.

        Restarted at the rests unless ``plain`` (one run from the start, as recorded).
        ``lean``: the re-simulation has only the columns the residuals read
        (the compared signals, and the slopes that place a foreign recording's
        at its states), not the energies and forces a report reads.
        """
        cols = self.lean_columns() if lean else None
        self.evaluations += 1
        overrides = dict(self.overrides, **values)
        try:
            if self.anchoring is not None and not plain:
                return self.anchoring.run(self.source.model(overrides), self.commands,
                                          self.forces, n, values=cols)
            if self.foreign and self.fit_delay and not plain and 'sensor_seed' not in values:
                return self._aligned(self.source.replay(overrides, n, interpolate=False,
                                                        values=cols), n)
            if n is None or self.foreign:
                return self.source.replay(overrides, n, values=cols) if self.foreign else \
                    self.source.replay(overrides, values=cols)
            src = self.source          # the steps up to n only: the horizon of a fit stage
            parts, done = [], 0
            for part, part_cols in src.blocks(src.model(overrides), overrides=overrides,
                                              block_ticks=n, values=cols):
                parts.append(part_cols)
                done = part.k1
                if done >= n:
                    break
            return {k: np.concatenate([c[k] for c in parts]) for k in parts[0]} if parts \
                else {}
        except ParameterError as exc:
            raise RunError(f're-simulation with {values}: {exc}') from None

    @property
    def delay(self):
        """Return the command-to-state delay [s] of the last aligned re-simulation."""
        return self.source.delay.value + self.shift_ns / NS

    def _aligned(self, raw, n):
        """
        Return the columns of ``raw`` at the recorded states, shifted in time to fit them best.

        The recording's command-to-state delay is not known; its estimate
        (:mod:`leadscrew_sim.offline.foreign.delay`) is made with the starting
        values, and with friction far from the axis's the re-simulated lag
        differs, and so does the estimate (a velocity-mode run at the
        defaults was estimated 0.54 ms where it was -0.40 ms: a fit at it
        cannot explain its recording). The model is time-invariant, so a
        further delay shifts the re-simulated states alike: each
        re-simulation is compared at the shift, within +-``shift_range`` of
        the estimate, that minimises its weighted squared residuals: a grid of
        :data:`SHIFT_GRID` shifts, :data:`SHIFT_ROUNDS` times, each about the
        best of the one before and spanning two of its intervals, then the
        vertex of a parabola through the least three (each grid one
        vectorised interpolation). The delay is so fitted with the
        parameters at the cost of interpolations only (the shift is
        concentrated out).
        """
        meas, src = self.measurements, self.source
        n_run = len(next(iter(raw.values())))
        steps = src.k[src.k < min(n_run - 1, meas.n if n is None else n)]
        slope_of = {c: SLOPES.get(c) for c in meas.columns.values()}
        # the search on at most SHIFT_STATES states, evenly taken (the shift is one number)
        every = -(-len(steps) // SHIFT_STATES)
        rows = []
        for i, s in enumerate(meas.names):
            column = meas.columns[s]
            ok = meas.mask[i, steps] & (np.arange(len(steps)) % every == 0)
            v = None if slope_of[column] is None else \
                np.asarray(raw[slope_of[column]], dtype=float) * (src.dt_ns / NS)
            rows.append((np.asarray(raw[column], dtype=float), v, meas.data[i, steps][ok], ok,
                         1.0 / meas.sigma[s] ** 2, meas.offset[i]))

        def costs(shifts):      # the weighted squared residuals at the states, per shift
            k, frac = src.shifted_steps(shifts, steps, n_run, every)
            total = np.zeros(len(shifts))
            for y, v, data, ok, w2, off in rows:
                d = hermite(y, v, k[:, ok[::every]], frac[:, ok[::every]]) - data
                if off and d.shape[1]:
                    d = d - d.mean(axis=1, keepdims=True)
                total += np.einsum('ij,ij->i', d, d) * w2
            return total
        span = self.shift_range * NS
        centre, half = 0.0, span
        for _ in range(SHIFT_ROUNDS):   # ever finer grids about the best
            grid = centre + np.linspace(-half, half, SHIFT_GRID)
            c = costs(grid)
            i = int(np.argmin(c))
            centre, half = grid[i], 2.0 * half / (SHIFT_GRID - 1)
        best = centre
        if 0 < i < SHIFT_GRID - 1:      # the vertex of the parabola through the least three
            den = c[i - 1] - 2.0 * c[i] + c[i + 1]
            h = grid[1] - grid[0]
            if den > 0.0:
                best = centre + 0.5 * h * (c[i - 1] - c[i + 1]) / den
        self.shift_ns = int(round(best))
        return src.at_states(raw, self.shift_ns)

    def compared(self, cols):
        """Return the columns ``cols`` of a re-simulation at the steps some signal is compared."""
        used = self.measurements.mask.any(axis=0)
        return {k: np.asarray(v)[:len(used)][used[:len(v)]] for k, v in cols.items()}

    def lean_columns(self):
        """Return the re-simulated columns the residuals read: each signal's and its slope."""
        meas = self.measurements
        names = [meas.columns[s] for s in meas.names]
        return tuple(sorted(set(names) | {SLOPES[c] for c in names if c in SLOPES}))

    def residuals(self, values, n=None):
        """Return the weighted residuals of the first ``n`` steps (all: None); show progress."""
        r = self.measurements.residuals(self.replay(values, n, lean=True), n)
        if self.progress is not None:
            if n is None:
                self.misfit = rms_per_signal(self.measurements.names, r)
            stage = self.stage if n is None else f'{self.stage}, first {n} of {self.n} steps'
            self.progress.update(stage, self.evaluations, self.misfit)
        return r
