"""
The library calls of the frequency response: linear model and simulated measurement.

:func:`linear_response` gives the FRF of the linearised axis (one
:class:`.FrequencyResponse`, amplitude NaN); :func:`simulated_response` that
of the full nonlinear model under a sine dwell, a multisine or a chirp (one
per amplitude). Both take an input and an output (:data:`.linear.INPUTS`,
:data:`.linear.OUTPUTS`), or a loop (``velocity`` / ``position``) and a
quantity (``L``, ``S``, ``T``). :func:`check_request` refuses bad input with
a ParameterError that names the parameter, the value and the allowed range.
"""
import math

import numpy as np

from ...core.drive_control import drive_period
from ...core.params import ParameterError
from .broadband import chirp_response, multisine_response
from .linear import closed_loop, INPUTS, LOOPS, MODES, OUTPUTS, QUANTITIES, SAMPLINGS
from .loops import loop_gain, loop_response
from .parallel import run_points
from .plant import check_servo, thread_state
from .response import FrequencyResponse
from .sine import _loop_pair, grid_frequency

__all__ = ['check_request', 'default_amplitude', 'frequencies', 'linear_response',
           'measurement_step', 'METHODS', 'simulated_response']

METHODS = ('sine', 'chirp', 'multisine')


def _one_of(name, value, allowed):
    if value not in allowed:
        raise ParameterError(name, f'{value!r} is not one of {", ".join(allowed)}')


def check_request(input=None, output=None, loop=None, quantity=None, fmin=None, fmax=None,
                  points=None, amplitudes=(), dt=1e-3):
    """
    Refuse a bad request: unknown names, a band beyond Nyquist, a non-positive amplitude.

    Raises ParameterError naming the parameter, the value and the allowed range.
    """
    if loop is not None:
        _one_of('loop', loop, LOOPS)
        _one_of('quantity', quantity, QUANTITIES)
    else:
        _one_of('input', input, INPUTS)
        _one_of('output', output, OUTPUTS)
    nyq = 0.5 / dt
    for name, f in (('fmin', fmin), ('fmax', fmax)):
        if f is not None and not (math.isfinite(f) and 0.0 < f < nyq):
            raise ParameterError(name, f'{f!r} Hz is outside (0, {nyq:g}) Hz: above the '
                                 f'Nyquist frequency of the {1.0 / dt:g} Hz step rate'
                                 if f >= nyq else f'{f!r} Hz must be positive and finite')
    if fmin is not None and fmax is not None and not fmin < fmax:
        raise ParameterError('fmin', f'{fmin!r} Hz must be below fmax {fmax!r} Hz')
    if points is not None and not (2 <= int(points) <= 10000):
        raise ParameterError('points', f'{points!r} is outside [2, 10000]')
    for a in amplitudes:
        if not (math.isfinite(a) and a > 0.0):
            raise ParameterError('amplitude', f'{a!r} must be positive and finite (> 0)')


def frequencies(fmin, fmax, points):
    """Return ``points`` log-spaced frequencies [Hz] from fmin to fmax."""
    return np.geomspace(fmin, fmax, int(points))


def default_amplitude(params, input=None, loop=None):
    """
    Return the default test amplitude in the input's unit, from the axis.

    torque, velocity loop: 10 % of max_torque [N m]; velocity_command: 10 %
    of the velocity limit as a nut speed [m/s]; position_command: 1 % of it
    over 1 s [m]; external_force: 10 % of the moving weight (at least 1 N)
    [N]; position loop: 10 % of the velocity limit [rad/s].
    """
    p = params
    v_nut = p.velocity_limit * p.lead_ratio
    if loop == 'velocity' or input == 'torque':
        return 0.1 * p.max_torque
    if loop == 'position':
        return 0.1 * p.velocity_limit
    return {'velocity_command': 0.1 * v_nut, 'position_command': 0.01 * v_nut,
            'external_force': max(1.0, 0.1 * p.moving_mass * p.gravity)}[input]


def linear_response(params, input=None, output=None, loop=None, quantity=None,
                    frequency=None, speed=0.0, sampling='continuous', dt=1e-3, mode=None,
                    rest='stuck'):
    """
    Return the :class:`FrequencyResponse` of the linearised axis.

    Parameters
    ----------
    params : ScrewParams
        The axis.
    input, output : str
        Signal names (or give loop and quantity).
    loop, quantity : str
        'velocity' / 'position', and 'L' / 'S' / 'T'.
    frequency : array_like
        [Hz].
    speed : float
        Operating point nut speed [m/s] (0: at rest on the loaded flank).
    sampling : str
        'continuous', 'drive' or 'step' (see :mod:`.linear`).
    dt : float
        Step [s].
    mode : str, optional
        Drive mode under an external force (default position).
    rest : str
        At rest: 'stuck' (the thread held by stiction) or 'free' (its friction left out).

    """
    check_request(input, output, loop, quantity)
    _one_of('sampling', sampling, SAMPLINGS)
    f = np.asarray(frequency, dtype=float)
    state = thread_state(params, speed, rest)
    if loop is not None:
        h, note = loop_response(params, loop, quantity, f, speed, sampling, dt, rest)
        lg, _ = loop_gain(params, loop, f, speed, sampling, dt, rest)
        return FrequencyResponse(f, h, np.full(len(f), math.nan), math.nan, f'{loop}_loop',
                                 quantity, 'linear', [note], loop_gain=lg, state=state)
    cl = closed_loop(params, input, output, speed, mode, rest)
    h, notes = cl.response(f, sampling, dt)
    sys_c = cl.system('continuous')
    return FrequencyResponse(f, h, np.full(len(f), math.nan), math.nan, input, output, 'linear',
                             notes, poles=sys_c.poles(), zeros=sys_c.zeros(), state=state)


def measurement_step(params, dt, loop=None):
    """
    Return the step [s] a simulated measurement runs at: dt, or for a loop one drive period.

    A loop quantity is measured at the drive period, as a drive's own tuning
    tool samples it (the injection and the controller output then pair
    exactly, whatever the step rate); dt when the drive period does not map
    onto itself on the substep grid.
    """
    if loop is None:
        return dt
    td = drive_period(params, dt)
    return td if abs(drive_period(params, td) - td) <= 1e-12 * td else dt


def _settle_time(params, input, loop, speed, mode):
    """Return the settling time [s]: 4 time constants of the slowest mode, within [0.05, 1]."""
    try:
        if loop is not None:
            cl = closed_loop(params, 'velocity_command' if loop == 'velocity'
                             else 'position_command', 'motor_velocity', speed)
        else:
            cl = closed_loop(params, input, 'motor_velocity', speed, mode)
        re = -cl.system('continuous').poles().real
    except (ParameterError, np.linalg.LinAlgError):
        return 0.2
    scale = np.abs(re).max() if len(re) else 0.0
    slow = re[re > 1e-9 * scale]
    return float(min(1.0, max(0.05, 4.0 / slow.min()))) if len(slow) else 0.2


def simulated_response(params, input=None, output=None, loop=None, quantity=None,
                       method='sine', fmin=1.0, fmax=100.0, points=30, amplitudes=None,
                       dt=1e-3, speed=0.0, mode=None, settle=3, periods=5, workers=None,
                       scheduler=None):
    """
    Return a list of :class:`FrequencyResponse`, one per amplitude, measured on the full model.

    Parameters
    ----------
    params : ScrewParams
        The axis.
    input, output, loop, quantity : str
        As :func:`linear_response`.
    method : str
        'sine' (sine dwell), 'chirp' or 'multisine'.
    fmin, fmax : float
        Band [Hz], below the Nyquist frequency 1 / (2 dt).
    points : int
        Frequencies (sine: log-spaced, moved onto the step grid, repeats merged).
    amplitudes : sequence of float, optional
        Test amplitudes in the input's unit (default :func:`default_amplitude`).
    dt : float
        Step [s].
    speed : float
        Nut speed of the operating point [m/s]: 0 starts at rest; else the
        run starts sliding (sine dwell, velocity loop only; see :mod:`.drive_runs`).
    mode : str, optional
        Drive mode under an external force (default position).
    settle, periods : int
        Sine dwell: periods discarded (at least the settling time), periods kept.
    workers, scheduler
        Sine dwell: local worker processes, or a Dask scheduler address.

    """
    _one_of('method', method, METHODS)
    if loop is not None:
        check_servo(params, f'the {loop} loop')
    amps = [default_amplitude(params, input, loop)] if amplitudes is None else list(amplitudes)
    check_request(input, output, loop, quantity, fmin, fmax, points, amps, dt)
    mode = mode or 'position'
    _one_of('mode', mode, MODES)
    where = f'{loop}_loop' if loop else input
    dt = measurement_step(params, dt, loop)
    name_in, name_out = (where, quantity) if loop else (input, output)
    settle_time = _settle_time(params, input, loop, speed, mode)
    if int(settle) < 0 or int(periods) < 1:
        raise ParameterError('periods', f'settle {settle!r} and periods {periods!r}: need '
                             'settle >= 0 and periods >= 1')
    if method == 'sine':
        f = np.unique([grid_frequency(fi, dt)[0] for fi in frequencies(fmin, fmax, points)])
        tasks = [dict(where=where, output=output, frequency=fi, amplitude=a, dt=dt,
                      settle=settle, periods=periods, settle_time=settle_time, mode=mode,
                      quantity=quantity, speed=speed) for a in amps for fi in f]
        pts = run_points(params, tasks, workers, scheduler)
        note = (f'sine dwell: frequencies on the {1.0 / dt:g} Hz step grid, {settle} periods '
                f'(at least {settle_time:.3g} s) discarded, {periods} kept')
        return [_sine_response(pts[i * len(f):(i + 1) * len(f)], a, name_in, name_out, note)
                for i, a in enumerate(amps)]
    out = []
    if speed != 0.0:
        raise ParameterError('speed', f'{speed!r} m/s: {method} runs start at rest (speed 0); '
                             'the sine dwell and the linear model take a speed')
    pair = (lambda u, y: _loop_pair(u, y, quantity)) if loop else None
    for a in amps:
        if method == 'multisine':
            r = multisine_response(params, where, output, fmin, fmax, points, a, dt,
                                   max(2, int(periods)), settle_time, mode, pair)
            note = 'multisine: Schroeder phases, whole periods, per-period DFT'
        else:
            r = chirp_response(params, where, output, fmin, fmax, frequencies(fmin, fmax, points),
                               a, dt, None, settle_time, mode, pair)
            note = 'chirp: logarithmic sweep, H1 and coherence by Welch (Hann, 50 % overlap)'
        out.append(FrequencyResponse(r['frequency'], r['response'], r['coherence'], a, name_in,
                                     name_out, method, [note]))
    return out


def _sine_response(points, amplitude, name_in, name_out, note):
    """Return the :class:`FrequencyResponse` of one amplitude's sine dwell points."""
    rows = _merge(points)
    bad = sum(1 for r in rows if not np.isfinite(r['response']))
    extra = [f'{bad} of {len(rows)} frequencies without a result (a drive fault '
             'latched or the run went non-finite: lower the amplitude)'] if bad else []
    return FrequencyResponse(np.array([r['frequency'] for r in rows]),
                             np.array([r['response'] for r in rows]),
                             np.array([r['coherence'] for r in rows]), amplitude, name_in,
                             name_out, 'sine', [note] + extra)


def _merge(rows):
    """Return the rows with repeated grid frequencies merged (the first kept), sorted."""
    seen, out = set(), []
    for r in sorted(rows, key=lambda r: r['frequency']):
        if r['frequency'] not in seen:
            seen.add(r['frequency'])
            out.append(r)
    return out
