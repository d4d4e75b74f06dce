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

from .analysis_calls import (excite, ExciteResult, freqresp, pullout, PulloutResult, recover,
                             resim, ResimResult, stability, StabilityResult)
from .call_options import (_mapping_fields, _number, _opt_sets, _recording, _sets, Mapping,
                           open_recording, Options, Recording, RunError)
from .info import info, InfoResult
from .options import open_recording as _open, option_text

__all__ = ['CommissionResult', 'ExciteResult', 'IdentifyResult', 'InfoResult', 'Mapping',
           'Options',
           'PulloutResult', 'Recording', 'ResimResult', 'SimulateResult', 'StabilityResult',
           'commission', 'excite', 'freqresp', 'identify', 'identify_options', 'info',
           'open_recording', 'pullout', 'recover', 'resim', 'simulate', 'stability']


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
        verdicts[name], reasons[name] = vd.status, option_text(vd.reason)
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
