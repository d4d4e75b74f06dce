"""
The offline tools as Python calls: keyword options in, a result with named fields out.

``leadscrew_sim.simulate``, ``open_recording``, ``identify`` and
``commission`` are these functions (``import leadscrew_sim as ls``). Their
keywords are the command line's options in snake_case, with the same
defaults and units; the verbs of the command line call the same run
library. Every error they raise derives from
:class:`leadscrew_sim.LeadscrewError` and names the parameter or option,
the value and the allowed range::

    import leadscrew_sim as ls
    run = ls.simulate('tr12x3', excite='commission', set={'mu_s': 0.25}, output='run.mcap')
    rec = ls.open_recording('run.mcap')
    fit = ls.identify(rec, fit=['mu_s', 'mu_k', 'stribeck_velocity'])
    fit.values['mu_k'], fit.intervals['mu_k'], fit.verdicts['mu_k']
    com = ls.commission(rec, 'out/')

The options travel to the run library as a plain record of fields
(:class:`Options`), never as parsed command-line arguments.
"""
import dataclasses
import math
import os
from pathlib import Path
import tempfile

import numpy as np

from .foreign.mapping import Mapping
from .options import open_recording as _open, RunError

__all__ = ['CommissionResult', 'ExciteResult', 'IdentifyResult', 'Mapping', 'Options',
           'PulloutResult', 'Recording', 'ResimResult', 'SimulateResult', 'StabilityResult',
           'commission', 'excite', 'freqresp', 'identify', 'identify_options',
           'open_recording', 'pullout', 'recover', 'resim', 'simulate', 'stability']


class Options:
    """The options of one call as named fields (what the run library reads)."""

    def __init__(self, **fields):
        """Keep ``fields``."""
        self.__dict__.update(fields)

    def __repr__(self):
        """Return the fields."""
        return f'Options({self.__dict__!r})'


def _number(name, value, unit, lo=None, hi=None, lo_open=False, optional=True):
    """
    Check the numeric option ``name`` where it enters; return it (None passes if optional).

    Raises RunError naming the option, its value [unit] and the allowed range.
    """
    if value is None and optional:
        return None
    ok = (isinstance(value, (int, float)) and not isinstance(value, bool)
          and math.isfinite(value))
    if ok and lo is not None:
        ok = value > lo if lo_open else value >= lo
    if ok and hi is not None:
        ok = value <= hi
    if not ok:
        if lo is None and hi is None:
            raise RunError(f"option '{name}': {value!r} {unit} must be a finite number")
        rng = f'{"(" if lo_open else "["}{lo}, {hi}]'
        raise RunError(f"option '{name}': {value!r} {unit} is outside the allowed range {rng}")
    return value


def _sets(values):
    """Return ``{name: value}`` as the run library's NAME=VALUE items (None: none)."""
    if values is None:
        return None
    if not isinstance(values, dict):
        raise RunError(f'set: {values!r} must be a dict {{parameter name: value}}')
    return [f'{k}={v!r}' if isinstance(v, float) else f'{k}={v}' for k, v in values.items()]


def _opt_sets(values):
    """Return ``{name: value}`` of an excitation profile's options as NAME=VALUE items."""
    return None if values is None else [f'{k}={v}' for k, v in dict(values).items()]


# ---------------------------------------------------------------------------------- simulate
@dataclasses.dataclass(frozen=True)
class SimulateResult:
    """
    A simulated run: its per-tick arrays and the file it wrote.

    Attributes
    ----------
    time : numpy.ndarray
        Time of each tick [s] from the start.
    nut_position : numpy.ndarray
        The nut position the node publishes on ``nut_position`` at each tick [m].
    path : str or None
        The MCAP file written (None: ``output`` was not given; the run's
        temporary file is gone).
    rate : float
        Update rate [Hz].
    steps : int
        Ticks run [-].
    events : list
        The run's events (faults, protections) as the recording holds them.
    ageing : dict
        The ageing of each tick (``sim/ageing``): wear_leading, wear_trailing
        [m], backlash [m], preload [N], lubricant [-], mu_k, mu_s [-],
        screw_temperature [degC], heat_flow [W], thermal_growth [m]; arrays
        as long as ``time``.

    """

    time: np.ndarray
    nut_position: np.ndarray
    path: object
    rate: float
    steps: int
    events: list
    ageing: dict = dataclasses.field(default_factory=dict)


def simulate(preset=None, *, params=None, set=None, duration=None, update_rate=None,
             torque=None, torque_csv=None, profile=None, velocity=None, velocity_csv=None,
             position=None, position_csv=None, accel=0.1, amplitude=None, frequency=1.0,
             step_time=0.1, target=None, speed=0.01, excite=None, excite_opt=None,
             force=None, force_csv=None, faults=None, clock=False, compression='lz4',
             output=None, ageing_from=None):
    """
    Run the model offline as ``leadscrew_sim simulate`` does; return a :class:`SimulateResult`.

    Parameters
    ----------
    preset : str, optional
        Preset name or YAML path (default tr12x3).
    params : str, optional
        A ROS 2 parameter file.
    set : dict, optional
        Parameter values {name: value}, each in its parameter's unit.
    duration : float, optional
        Simulated time [s] (default 1, or the ``excite`` profile's).
    update_rate : float, optional
        Update rate [Hz] (default 1000).
    torque : float, optional
        Constant motor torque [N m].
    torque_csv : str, optional
        A CSV series: time [s], motor torque [N m].
    profile : str, optional
        step, ramp, sine, move or trapezoid.
    accel : float
        Trapezoid acceleration [m/s^2].
    amplitude : float, optional
        Amplitude of the step, ramp or sine profile [N m].
    frequency : float
        Sine frequency [Hz].
    step_time : float
        Time of the step [s].
    target : float, optional
        Target of the move [m] (default the initial position + 10 mm).
    speed : float
        Reference speed of the move [m/s].
    velocity : float, optional
        A constant nut velocity command [m/s] for the drive.
    velocity_csv : str, optional
        A CSV series: time [s], nut velocity [m/s].
    position : float, optional
        A constant nut position target [m] for the drive.
    position_csv : str, optional
        A CSV series: time [s], nut position [m].
    excite : str, optional
        A profile of ``leadscrew_sim excite`` (breakaway, sweep, commission, ...).
    excite_opt : dict, optional
        The profile's options {option: value}.
    force : float, optional
        Constant external axial force [N].
    force_csv : str, optional
        A CSV series: time [s], axial force [N].
    faults : str, optional
        A fault schedule CSV.
    clock : bool
        Also record /clock every tick.
    compression : str
        lz4, zstd or none.
    output : str, optional
        The MCAP file to write (None: a temporary one, removed).
    ageing_from : str, optional
        A recording of the same axis: start from the ageing state (wear,
        lubricant, screw temperature) it ended with.

    Raises
    ------
    leadscrew_sim.LeadscrewError
        A bad option or parameter (named, with its value and range), or a
        failed integration.

    """
    from .simulate.run import simulate as run_simulate
    from ..io.run_file import PARAMS_RECORD  # noqa: F401 - the run file's layout is io's
    _number('duration', duration, 's', 0.0, math.inf, lo_open=True)
    _number('update_rate', update_rate, 'Hz', 1.0, 1e6)
    for name, value, unit in (('torque', torque, 'N m'), ('velocity', velocity, 'm/s'),
                              ('position', position, 'm'), ('amplitude', amplitude, 'N m'),
                              ('target', target, 'm'), ('force', force, 'N')):
        _number(name, value, unit)
    _number('accel', accel, 'm/s^2', 0.0, math.inf, lo_open=True, optional=False)
    _number('frequency', frequency, 'Hz', 0.0, math.inf, lo_open=True, optional=False)
    _number('step_time', step_time, 's', 0.0, math.inf, optional=False)
    _number('speed', speed, 'm/s', 0.0, math.inf, lo_open=True, optional=False)
    tmp = None
    path = output
    if path is None:
        tmp = tempfile.TemporaryDirectory(prefix='leadscrew_sim_')
        path = os.path.join(tmp.name, 'run.mcap')
    opts = Options(preset=preset, params=params, set=_sets(set), duration=duration,
                   rate=update_rate, torque=torque, torque_csv=torque_csv, profile=profile,
                   velocity=velocity, velocity_csv=velocity_csv, position=position,
                   position_csv=position_csv, accel=accel, amplitude=amplitude,
                   frequency=frequency, step_time=step_time, target=target, speed=speed,
                   excite=excite, excite_opt=_opt_sets(excite_opt), force=force,
                   force_csv=force_csv, faults=faults, clock=clock, compression=compression,
                   output=str(path), quiet=True, ageing_from=ageing_from)
    try:
        done = run_simulate(opts, lambda text: None)
        time, x = _nut_positions(path)
        return SimulateResult(time=time, nut_position=x,
                              path=None if tmp is not None else str(done.path),
                              rate=float(done.rate), steps=int(done.steps),
                              events=list(done.events or []), ageing=_ageing(path))
    finally:
        if tmp is not None:
            tmp.cleanup()


def _nut_positions(path):
    """Return (time [s], nut position [m]) of the ``nut_position`` messages of a run file."""
    rec = _open(path)
    arrays = (rec.topic_arrays(['/nut_position']) or {}).get('/nut_position')
    if arrays is None or not len(arrays.log_times):
        return np.zeros(0), np.zeros(0)
    data = arrays.messages()
    x = np.array([np.frombuffer(m, dtype='<f8', count=1, offset=4)[0] for m in data])
    t = (np.asarray(arrays.log_times, dtype=np.int64) - int(arrays.log_times[0])) / 1e9
    return t, x


def _ageing(path):
    """Return {field: array} of the ``sim/ageing`` messages of a run file (its AgeingState)."""
    from ..io.messages import AGEING_VALUES, decode_ageing
    arrays = (_open(path).topic_arrays(['/sim/ageing']) or {}).get('/sim/ageing')
    if arrays is None or not len(arrays.log_times):
        return {name: np.zeros(0) for name in AGEING_VALUES}
    rows = [decode_ageing(m)[1] for m in arrays.messages()]
    return {name: np.array([r[name] for r in rows]) for name in AGEING_VALUES}


# ----------------------------------------------------------------------------- recordings
@dataclasses.dataclass(frozen=True)
class Recording:
    """
    A recording to analyse: an MCAP file or a rosbag2 directory, and its mapping.

    ``mapping``: how a foreign recording's topics and joints map onto the
    axis (:class:`Mapping`; None: a leadscrew_sim recording, or the node's
    own topic and joint names).
    """

    path: str
    mapping: object = None


def open_recording(path, mapping=None):
    """
    Open an MCAP file or a rosbag2 directory for the calls; return a :class:`Recording`.

    Raises a :class:`leadscrew_sim.LeadscrewError` when it cannot be read.
    """
    if mapping is not None and not isinstance(mapping, Mapping):
        raise RunError(f'mapping: {mapping!r} must be a leadscrew_sim.Mapping')
    rec = _open(path)
    rec.require_ros2()
    return Recording(str(path), mapping)


def _recording(rec):
    """Return a :class:`Recording` of ``rec`` (a path is opened)."""
    return rec if isinstance(rec, Recording) else open_recording(rec)


def identify_options(file, *, preset=None, params=None, set_items=None, mapping=None,
                     map_file=None, fit=None):
    """
    Return the fields the fit of ``identify`` reads, as :class:`Options`.

    ``set_items``: NAME=VALUE texts; ``mapping``: a :class:`Mapping` whose
    given fields win over ``map_file`` (a mapping YAML file).
    """
    fields = _mapping_fields(mapping)
    fields['map'] = map_file
    return Options(file=str(file), fit=fit, preset=preset, params=params, set=set_items,
                   output_params=None, report=None, plot=None, max_nfev=None,
                   restarts='auto', write_all=False, quiet=True, **fields)


def _mapping_fields(mapping):
    """Return the run library's mapping fields of a :class:`Mapping` (None: none given)."""
    m = mapping or Mapping()
    return dict(map=None, state_topic=m.state_topic, screw_joint=m.screw_joint,
                nut_joint=m.nut_joint, command_topic=m.command_topic,
                command_kind=m.command_kind, command_index=m.command_index,
                command_joint=m.command_joint, command_delay=m.command_delay,
                rate=m.step_rate)


# ------------------------------------------------------------------------------- identify
@dataclasses.dataclass(frozen=True)
class IdentifyResult:
    """
    A fit of ``identify``, in the manner of scipy's ``least_squares`` result.

    Attributes
    ----------
    values : dict
        name -> fitted value (its starting value when not fitted) [its unit].
    intervals : dict
        name -> (low, high) 95 % interval [its unit], or None (no interval:
        not identified, or exact data).
    verdicts : dict
        name -> 'identified', 'exact data' or 'not identifiable'.
    reasons : dict
        name -> the verdict's reason, one line.
    params : ScrewParams
        The starting set with the fitted values.
    misfit : dict
        signal -> RMS / sigma of the fit's residuals [-].
    delay : float or None
        A foreign recording's command-to-state delay used [s].
    nfev : int
        Re-simulations [-].
    wall : float
        Wall time [s].

    """

    values: dict
    intervals: dict
    verdicts: dict
    reasons: dict
    params: object
    misfit: dict
    delay: object
    nfev: int
    wall: float


def identify(recording, *, fit=None, preset=None, params=None, set=None, max_nfev=None,
             restarts='auto'):
    """
    Fit physical parameters to a recording as ``leadscrew_sim identify``; return an IdentifyResult.

    Parameters
    ----------
    recording : Recording or str
        From :func:`open_recording` (with its mapping), or a path.
    fit : list of str, optional
        The parameters to fit (default mu_s, mu_k, stribeck_velocity,
        mu_viscous, backlash, bearing_coulomb, guide_coulomb).
    preset, params : str, optional
        Starting and fixed values: a preset, or a ROS 2 parameter file
        (default: the preset the recording names, else tr12x3).
    set : dict, optional
        Starting or fixed values {name: value} [their units].
    max_nfev : int, optional
        Most re-simulations per fit stage [-].
    restarts : str
        auto, on or off: restarts at the rests of a torque-mode recording.

    Raises
    ------
    leadscrew_sim.LeadscrewError
        A bad option or parameter, or a recording that does not map.

    """
    from .identify.run import fit_recording
    rec = _recording(recording)
    if fit is not None and (isinstance(fit, str) or not all(isinstance(n, str) for n in fit)):
        raise RunError(f'fit: {fit!r} must be a list of parameter names')
    if restarts not in ('auto', 'on', 'off'):
        raise RunError(f'restarts: {restarts!r} must be auto, on or off')
    if max_nfev is not None and not (isinstance(max_nfev, int) and max_nfev >= 1):
        raise RunError(f'max_nfev: {max_nfev!r} must be an integer >= 1')
    opts = Options(file=rec.path, fit=None if fit is None else ','.join(fit), preset=preset,
                   params=params, set=_sets(set), output_params=None, report=None,
                   plot=None, max_nfev=max_nfev, restarts=restarts, write_all=False,
                   quiet=True, **_mapping_fields(rec.mapping))
    return _identify_result(fit_recording(opts))


def _identify_result(out):
    """Return the :class:`IdentifyResult` of what ``fit_recording`` returned."""
    res, problem = out['res'], out['problem']
    values, intervals, verdicts, reasons = {}, {}, {}, {}
    for name, value, vd in zip(res.names, res.values, res.verdicts):
        values[name] = float(value) if vd.fitted else float(getattr(out['params'], name))
        ok = vd.identified and math.isfinite(vd.lower) and math.isfinite(vd.upper)
        intervals[name] = (float(vd.lower), float(vd.upper)) if ok else None
        verdicts[name], reasons[name] = vd.status, vd.reason
    final = out.get('final')
    misfit = {}
    if final is not None:
        meas = problem.measurements
        for name, rms in zip(meas.names, meas.rms(final)):
            misfit[name] = float(rms / meas.sigma[name])
    delay = float(problem.delay) if problem.foreign else None
    return IdentifyResult(values=values, intervals=intervals, verdicts=verdicts,
                          reasons=reasons, params=out['params'], misfit=misfit, delay=delay,
                          nfev=int(res.nfev), wall=float(out['wall']))


# ----------------------------------------------------------------------------- commission
@dataclasses.dataclass(frozen=True)
class CommissionResult:
    """
    A commissioning: the report and the fit it wrote.

    ``report``: the dict written as report.json; ``fit``: the
    :class:`IdentifyResult` of its fit (None: no fit); ``directory``: where
    fit.yaml, report.json and report.html are.
    """

    report: dict
    fit: object
    directory: str


def commission(recording, output, *, segments=None, preset=None, params=None, set=None):
    """
    Commission the axis of a recording as ``leadscrew_sim commission``; return a CommissionResult.

    Parameters
    ----------
    recording : Recording or str
        From :func:`open_recording` (with its mapping), or a path.
    output : str
        The directory of fit.yaml, report.json and report.html (created).
    segments : str, optional
        A segments sidecar JSON file.
    preset, params, set
        Starting and fixed values, as :func:`identify` takes them.

    """
    from .commission.run import commission as run_commission
    rec = _recording(recording)
    opts = identify_options(rec.path, preset=preset, params=params, set_items=_sets(set),
                            mapping=rec.mapping)
    held = {}
    report = run_commission(rec.path, str(output), opts, segments, progress=lambda line: None,
                            keep=held)
    fit = held.get('fit')
    return CommissionResult(report=report, fit=None if fit is None else _identify_result(fit),
                            directory=str(Path(output)))


# ---------------------------------------------------------------------------------- resim
@dataclasses.dataclass(frozen=True)
class ResimResult:
    """
    A recording re-simulated and compared, as ``leadscrew_sim resim`` prints it.

    Attributes
    ----------
    path : str or None
        The MCAP file written (None for a foreign recording: its twin is not written).
    rows : list of dict
        One per compared field: topic, field, max_diff, rms_diff (in the
        field's unit) and n (values compared).
    bit_identical : bool
        Every compared value has the recorded bits.
    ticks : int
        Recorded ticks compared [-].
    events : list
        The run's events (faults, protections).
    comparison : object
        For a foreign recording, the twin's comparison (its report lines
        come from :func:`leadscrew_sim.offline.foreign.twin.report_lines`); else None.

    """

    path: object
    rows: list
    bit_identical: bool
    ticks: int
    events: list
    comparison: object = None


def resim(recording, *, set=None, output=None, compression='lz4', preset=None, params=None):
    """
    Re-run a recording's commands through the model; compare the states it recorded.

    Parameters
    ----------
    recording : Recording or str
        An MCAP file or a rosbag2 directory (:func:`open_recording`). A
        leadscrew_sim recording re-runs with its own parameters; a foreign
        one, or one given ``preset``/``params`` or a mapping, is compared with
        its twin.
    set : dict, optional
        Physics parameters to override {name: value}, each in its unit.
    output : str, optional
        The MCAP file to write (default <stem>.resim.mcap beside the recording).
    compression : str
        lz4, zstd or none.
    preset : str, optional
        The twin's preset (a foreign recording).
    params : str, optional
        The twin's ROS 2 parameter file (a foreign recording).

    Raises
    ------
    leadscrew_sim.LeadscrewError
        A bad option, parameter or recording (named, with its value).

    """
    from .replay.run import resim as run_resim, TwinRun
    rec = _recording(recording)
    opts = Options(file=rec.path, set=_sets(set), output=output, compression=compression,
                   quiet=True, preset=preset, params=params, plot=None,
                   **_mapping_fields(rec.mapping))
    done = run_resim(opts)
    if isinstance(done, TwinRun):
        return ResimResult(path=None, rows=[], bit_identical=False, ticks=0, events=[],
                           comparison=done.comparison)
    rows = [dict(topic=t, field=f, max_diff=float(mx), rms_diff=float(rms), n=int(n))
            for t, f, mx, rms, n in done.rows]
    identical = done.ticks > 0 and not done.bit_differences and all(
        r['max_diff'] == 0.0 for r in rows if r['n'])
    return ResimResult(path=str(done.path), rows=rows, bit_identical=identical,
                       ticks=int(done.ticks), events=list(done.events or []))


# --------------------------------------------------------------------------------- excite
@dataclasses.dataclass(frozen=True)
class ExciteResult:
    """
    An excitation profile as arrays: what ``leadscrew_sim excite`` would publish.

    Attributes
    ----------
    time : numpy.ndarray
        Time of each command from the start [s], at the command rate.
    values : numpy.ndarray
        The command at each time, in ``unit``.
    topic : str
        The command topic (torque_command, velocity_command or position_command;
        a chained profile's first).
    unit : str
        The unit of the values (N m, m/s or m).
    segments : list of tuple
        (start [s], end [s], label) of each part of the profile.
    options : dict
        Every option of the profile, defaults filled in (SI units).
    duration : float
        The profile's duration [s].

    """

    time: np.ndarray
    values: np.ndarray
    topic: str
    unit: str
    segments: list
    options: dict
    duration: float


def excite(name, preset=None, *, params=None, set=None, opt=None, command_rate=None):
    """
    Build an excitation profile for an axis; return its commands as arrays.

    Parameters
    ----------
    name : str
        The profile: breakaway, sweep, reversals, iso230, warmup, chirp,
        multisine or commission.
    preset : str, optional
        Preset name or YAML path of the axis (default tr12x3).
    params : str, optional
        A ROS 2 parameter file of the axis.
    set : dict, optional
        Parameters of the axis {name: value}, each in its unit.
    opt : dict, optional
        The profile's options {option: value} in SI units.
    command_rate : float, optional
        Commands per second [Hz] (default the profile's own, else 100).

    Raises
    ------
    leadscrew_sim.LeadscrewError
        An unknown profile, a bad option (named, with its value and range).

    """
    from .options import load_params, parse_options, parse_sets
    from ..analysis.excitation.profiles import make_profile
    phys, _run = parse_sets(_sets(set))
    p, _label, _extra = load_params(Options(preset=preset, params=params), phys)
    profile = make_profile(name, p, **parse_options(_opt_sets(opt)))
    rate = command_rate if command_rate is not None else getattr(profile, 'command_rate',
                                                                 100.0)
    if not (isinstance(rate, (int, float)) and math.isfinite(rate) and 0.1 <= rate <= 1e4):
        raise RunError(f'command_rate: {rate!r} Hz is outside the allowed range [0.1, 10000]')
    n = int(math.ceil(profile.duration * rate - 1e-9)) + 1
    t = np.arange(n) / rate
    return ExciteResult(time=t, values=profile.values(t), topic=profile.topic,
                        unit=profile.unit, options=dict(profile.options),
                        segments=[(s.t0, s.t1, s.label) for s in profile.segments],
                        duration=float(profile.duration))


# -------------------------------------------------------------------------------- pullout
@dataclasses.dataclass(frozen=True)
class PulloutResult:
    """
    A stepper axis's pull-out curve, as ``leadscrew_sim pullout`` prints it.

    Attributes
    ----------
    step_rate : numpy.ndarray
        Step rates [full steps/s].
    speed : numpy.ndarray
        The motor speed at each [rev/s].
    pullout_torque : numpy.ndarray
        The load torque the motor pulls out at [N m].

    """

    step_rate: np.ndarray
    speed: np.ndarray
    pullout_torque: np.ndarray


def pullout(preset=None, *, params=None, set=None, rates=None, ramp=2.0, output=None,
            plot=None):
    """
    Measure a stepper axis's pull-out torque against step rate; return a :class:`PulloutResult`.

    Parameters
    ----------
    preset : str, optional
        Preset name or YAML path of a stepper axis (e.g. nema17_tr8x8).
    params : str, optional
        A ROS 2 parameter file of the axis.
    set : dict, optional
        Parameters {name: value}, each in its unit.
    rates : sequence of float, optional
        Step rates [full steps/s] (default 0.1, 0.2, ... 1 of max_step_rate).
    ramp : float
        Time of each load ramp to 1.2 holding torque [s].
    output : str, optional
        A CSV file to write the table to.
    plot : str, optional
        A PNG file to write the curve to.

    Raises
    ------
    leadscrew_sim.LeadscrewError
        A bad option or parameter, or an axis that is not a stepper.

    """
    from .options import load_params, parse_sets
    from .pullout import plot_png, pullout_curve, write_csv
    from ..core.presets import preset_label
    phys, _run = parse_sets(_sets(set))
    p, label, _extra = load_params(Options(preset=preset, params=params), phys)
    _number('ramp', ramp, 's', 0.0, math.inf, lo_open=True, optional=False)
    rows = pullout_curve(p, None if rates is None else [float(r) for r in rates], ramp)
    if output:
        write_csv(rows, output)
    if plot:
        plot_png(rows, p, preset_label(label), plot)
    return PulloutResult(*(np.array([r[k] for r in rows], dtype=float)
                           for k in ('step_rate', 'speed', 'pullout_torque')))


# ------------------------------------------------------------------------------ stability
@dataclasses.dataclass(frozen=True)
class StabilityResult:
    """
    The stability of steady sliding over a grid, as ``leadscrew_sim stability`` finds it.

    Attributes
    ----------
    rows : list of dict
        One per case: the grid values, growth_rate [1/s], frequency [Hz],
        mechanism, verdict, amplitude_large, stick_fraction, period [s], error.
    names : list of str
        The grid axes.
    boundaries : dict
        Axis name -> where the linear analysis changes verdict along it.
    bistable : dict
        Axis name -> (low, high) spans where a small start decays and a large one
        keeps oscillating.
    worst : dict or None
        The least stable case.
    complete : bool
        False when the run was interrupted.

    """

    rows: list
    names: list
    boundaries: dict
    bistable: dict
    worst: object
    complete: bool


def _grid_items(grid):
    """Return the run library's NAME=START:STOP:N[:log] items of ``grid``."""
    if grid is None:
        return []
    if not isinstance(grid, dict):
        raise RunError(f'grid: {grid!r} must be a dict {{name: (start, stop, n[, "log"])}}')
    items = []
    for name, axis in grid.items():
        if not isinstance(axis, (tuple, list)) or len(axis) not in (3, 4):
            raise RunError(f'grid: {name}={axis!r} must be (start, stop, n) or (start, stop, '
                           "n, 'log')")
        items.append(f'{name}=' + ':'.join(str(v) for v in axis))
    return items


def stability(preset=None, *, params=None, set=None, speed=None, drive='velocity', grid=None,
              method='both', duration=2.0, workers=None, scheduler=None, output=None,
              plot=None):
    """
    Map when the axis stick-slips or squeals; return a :class:`StabilityResult`.

    Parameters
    ----------
    preset : str, optional
        Preset name or YAML path (default tr12x3).
    params : str, optional
        A ROS 2 parameter file of the axis.
    set : dict, optional
        Parameters {name: value}, each in its unit.
    speed : float, optional
        Nut speed [m/s], its sign the direction along +x (unless speed is a grid axis).
    drive : str
        velocity (the servo velocity loop) or ideal (a prescribed motor angle).
    grid : dict, optional
        At most 3 axes {name: (start, stop, n) or (start, stop, n, 'log')}: the
        speed [m/s] or a numeric model parameter [its unit].
    method : str
        linear, nonlinear or both.
    duration : float
        Length of each nonlinear run [s].
    workers : int, optional
        Local worker processes (default the cores).
    scheduler : str, optional
        A Dask scheduler, tcp://HOST:PORT.
    output : str, optional
        A CSV file of the table.
    plot : str, optional
        A PNG file of the map.

    Raises
    ------
    leadscrew_sim.LeadscrewError
        A bad option or parameter (named, with its value and range).

    """
    from .options import load_params, parse_sets
    from ..analysis.stability import stability_table
    _number('speed', speed, 'm/s')
    _number('duration', duration, 's', 0.0, math.inf, lo_open=True, optional=False)
    phys, _run = parse_sets(_sets(set))
    p, _label, _extra = load_params(Options(preset=preset, params=params), phys)
    if workers is not None and not (isinstance(workers, int) and workers >= 1):
        raise RunError(f'workers: {workers!r} must be an integer of at least 1')
    res = stability_table(p, _grid_items(grid), speed=speed, drive=drive, method=method,
                          duration=duration, workers=workers, scheduler=scheduler,
                          csv_path=output, plot_path=plot, progress=False)
    if len(res['rows']) == 1 and res['rows'][0]['error']:
        raise RunError(res['rows'][0]['error'])
    return StabilityResult(rows=list(res['rows']), names=list(res['names']),
                           boundaries=dict(res['boundaries']),
                           bistable=dict(res.get('bistable', {})), worst=res['worst'],
                           complete=bool(res['complete']))


# ------------------------------------------------------------------------------- freqresp
def freqresp(recording=None, *, preset=None, params=None, set=None, input=None, output=None,
             loop=None, quantity=None, mode=None, speed=0.0, rest='stuck', linear=False,
             sampling='continuous', method='sine', fmin=None, fmax=None, points=30,
             amplitude=None, settle=3, periods=5, step_rate=None, workers=None,
             scheduler=None, segments=8, output_csv=None, plot=None):
    """
    Measure or compute the axis's frequency response; return a list of FrequencyResponse.

    From the linearised model (``linear=True``), a simulated measurement
    (``method``: sine dwell, chirp or multisine), or a ``recording`` with
    broadband excitation (its mapping from :func:`open_recording`). Each
    :class:`leadscrew_sim.analysis.freqresp.response.FrequencyResponse` holds
    ``frequency`` [Hz], the complex ``response`` in the signals' SI units,
    ``coherence``, ``amplitude`` and, for the linear model, ``poles``.

    Parameters
    ----------
    recording : Recording or str, optional
        A recording to measure (None: the model of ``preset``/``params``).
    preset, params : str, optional
        The axis: a preset or a ROS 2 parameter file.
    set : dict, optional
        Parameters {name: value}, each in its unit.
    input : str, optional
        torque [N m], velocity_command [m/s], position_command [m] or
        external_force [N] (default velocity_command).
    output : str, optional
        motor_angle [rad], motor_velocity [rad/s], nut_position [m],
        nut_velocity [m/s], thread_force [N], following_error [rad] or
        motor_torque [N m] (default motor_velocity).
    loop : str, optional
        velocity or position: a loop quantity instead of input/output.
    quantity : str, optional
        L, S or T with ``loop`` (default L).
    mode : str, optional
        The drive mode under an external_force input: torque, velocity, position.
    speed : float
        Operating point: nut speed [m/s] (0: at rest on the loaded flank).
    rest : str
        The linear model at rest: stuck (held by stiction) or free.
    linear : bool
        The linearised model's response.
    sampling : str
        With ``linear``: continuous, drive or step.
    method : str
        Simulated measurement: sine, chirp or multisine.
    fmin, fmax : float, optional
        Frequency range [Hz] (default 1 to 100).
    points : int
        Frequencies [-].
    amplitude : float or sequence of float, optional
        Test amplitude(s) in the input's SI unit (default from the axis).
    settle, periods : int
        Sine dwell: periods discarded and kept.
    step_rate : float, optional
        Step rate [Hz] (default 1000; a recording's from its stamps).
    workers : int, optional
        Local worker processes.
    scheduler : str, optional
        A Dask scheduler, tcp://HOST:PORT.
    segments : int
        A recording: Welch segments.
    output_csv : str, optional
        A CSV file of frequency, magnitude, phase, coherence, amplitude.
    plot : str, optional
        A PNG file of the Bode plot.

    Raises
    ------
    leadscrew_sim.LeadscrewError
        A bad option or parameter (named, with its value and range).

    """
    from .freqresp.run import freqresp_run
    _number('speed', speed, 'm/s', optional=False)
    _number('fmin', fmin, 'Hz', 0.0, math.inf, lo_open=True)
    _number('fmax', fmax, 'Hz', 0.0, math.inf, lo_open=True)
    _number('step_rate', step_rate, 'Hz', 0.0, math.inf, lo_open=True)
    if not (isinstance(points, int) and points >= 1):
        raise RunError(f"option 'points': {points!r} must be an integer of at least 1")
    fields = dict(preset=preset, params=params, set=_sets(set), input=input, output=output,
                  loop=loop, quantity=quantity, mode=mode, speed=speed, rest=rest,
                  linear=linear, sampling=sampling, method=method, fmin=fmin, fmax=fmax,
                  points=points, settle=settle, periods=periods, step_rate=step_rate,
                  workers=workers, scheduler=scheduler, segments=segments,
                  output_csv=output_csv, plot=plot, quiet=True, file=None,
                  amplitude=None if amplitude is None else ','.join(
                      str(float(a)) for a in np.atleast_1d(amplitude)))
    if recording is not None:
        rec = _recording(recording)
        fields.update(_mapping_fields(rec.mapping), file=rec.path)
    return list(freqresp_run(Options(**fields))['responses'])


# -------------------------------------------------------------------------------- recover
def recover(recording, output=None, *, force=False):
    """
    Write a complete copy of a recording cut short by a crash; say what it saved and lost.

    Parameters
    ----------
    recording : str
        A cut MCAP file, or a rosbag2 bag directory (merged into one MCAP
        file); read only, never changed.
    output : str, optional
        The copy (default the source with ``.recovered.mcap``).
    force : bool
        Overwrite the copy if it exists.

    Returns
    -------
    leadscrew_sim.offline.recover.Recovered
        ``path``, ``topics`` (topic -> messages saved), ``log_times`` [ns],
        ``whole``, ``problem``, ``lost_bytes``.

    Raises
    ------
    leadscrew_sim.LeadscrewError
        A missing source, a copy that would replace it or exists.

    """
    from .recover import recover_recording
    return recover_recording(recording, output, force)
