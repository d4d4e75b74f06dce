"""
The analysis tools as Python calls: resim, excite, pullout, stability, freqresp, recover.

Each takes keyword options named as the command line's flags and returns a
result with named fields (:mod:`.library` re-exports them with simulate,
identify and commission).
"""
import dataclasses
import math

import numpy as np

from .call_options import (_mapping_fields, _number, _opt_sets, _recording, _sets, Options,
                           RunError)

__all__ = ['ExciteResult', 'PulloutResult', 'ResimResult', 'StabilityResult', 'excite',
           'freqresp', 'pullout', 'recover', 'resim', 'stability']


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
