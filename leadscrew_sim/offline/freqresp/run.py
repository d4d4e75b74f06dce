"""
The run library of ``leadscrew_sim freqresp``: the frequency response from three sources.

:func:`freqresp_run` takes the verb's options (an argparse namespace or any
object with the same attributes) and returns dict(responses, linear, lines):

- ``file`` given: the recording's H1 and coherence
  (:func:`leadscrew_sim.offline.freqresp.recording.recording_response`, imported
  when used), with the linear model of ``preset`` / ``params`` overlaid
  when one is named;
- ``linear``: the linearised model's FRF at the operating point (sampling
  ``continuous`` by default);
- else the simulated measurement (``method`` sine, chirp or multisine, one
  response per amplitude) with the linear model's exact step discretisation
  overlaid.

It writes the CSV (``output``) and the Bode PNG (``plot``) when asked; the
summary lines are those of :func:`leadscrew_sim.analysis.freqresp.summary.summary_lines`.
"""
import math

import numpy as np

from ..options import load_params, parse_sets, RunError
from ...analysis.freqresp.measure import (check_request, frequencies, linear_response,
                                          measurement_step, simulated_response)
from ...analysis.freqresp.output import plot_bode, write_csv
from ...analysis.freqresp.summary import summary_lines

__all__ = ['freqresp_run', 'parse_amplitudes']

#: Points of the linear model drawn over a measurement.
OVERLAY_POINTS = 400


def parse_amplitudes(text):
    """Return the amplitudes of ``A[,A2,...]`` (None for None); RunError on a bad number."""
    if text is None:
        return None
    out = []
    for item in str(text).split(','):
        try:
            out.append(float(item))
        except ValueError:
            raise RunError(f"<<amplitude>> '{item}' is not a number (give A[,A2,...] in the "
                           "input's SI unit, each > 0)") from None
    return out


def _get(args, name, default=None):
    v = getattr(args, name, default)
    return default if v is None else v


def _names(args):
    """Return (input, output, loop, quantity) with the defaults filled in."""
    loop = _get(args, 'loop')
    if loop is not None:
        return None, None, loop, _get(args, 'quantity', 'L')
    if _get(args, 'quantity') is not None:
        raise RunError('<<quantity>> needs <<loop>> velocity|position')
    return (_get(args, 'input', 'velocity_command'), _get(args, 'output', 'motor_velocity'),
            None, None)


def _linear(params, names, f, args, sampling, dt=None):
    inp, out, loop, qty = names
    dt = 1.0 / _get(args, 'step_rate', 1000.0) if dt is None else dt
    return linear_response(params, inp, out, loop, qty, f, _get(args, 'speed', 0.0), sampling,
                           dt, _get(args, 'mode'), _get(args, 'rest', 'stuck'))


def _recording(args):
    """Return (responses, linear or None) of a recording."""
    from .recording import recording_response, RecordingOptions
    if _get(args, 'loop') is not None:
        raise RunError('<<loop>>: a recording gives input -> output responses only')
    opts = RecordingOptions(
        input=_get(args, 'input'), output=_get(args, 'output', 'motor_velocity'),
        fmin=_get(args, 'fmin'), fmax=_get(args, 'fmax'), segments=_get(args, 'segments', 8),
        state_topic=_get(args, 'state_topic'), command_topic=_get(args, 'command_topic'),
        command_kind=_get(args, 'command_kind'), screw_joint=_get(args, 'screw_joint'),
        nut_joint=_get(args, 'nut_joint'), step_rate=_get(args, 'step_rate'),
        command_index=_get(args, 'command_index'), command_joint=_get(args, 'command_joint'),
        command_delay=_get(args, 'command_delay'), map_file=_get(args, 'map'))
    resp = recording_response(args.file, opts)
    linear = None
    params = _params(args) if _get(args, 'preset') or _get(args, 'params') else None
    if params is not None and params.drive_type == 'servo':     # a stepper: no linear model
        f = np.geomspace(resp.frequency[resp.frequency > 0].min(), resp.frequency.max(),
                         OVERLAY_POINTS)
        linear = _linear(params, (resp.input, resp.output, None, None), f, args, 'step')
    return [resp], linear


def _params(args):
    phys, _ = parse_sets(_get(args, 'set'))
    params, _, _ = load_params(args, phys)
    return params


def freqresp_run(args):
    """
    Run the verb's work and return dict(responses, linear, lines); write CSV and PNG if asked.

    Parameters
    ----------
    args : argparse.Namespace
        The verb's options (see :mod:`leadscrew_sim.cli.freqresp`).

    """
    if _get(args, 'file'):
        responses, linear = _recording(args)
    else:
        params = _params(args)
        names = _names(args)
        rate = _get(args, 'step_rate', 1000.0)
        if not (math.isfinite(rate) and rate > 0.0):
            raise RunError(f'<<step_rate>> {rate!r} Hz must be positive')
        dt = 1.0 / rate
        fmin, fmax, points = (_get(args, 'fmin', 1.0), _get(args, 'fmax', 100.0),
                              _get(args, 'points', 30))
        amps = parse_amplitudes(_get(args, 'amplitude'))
        check_request(*names, fmin, fmax, points, amps or (), dt)
        if _get(args, 'linear', False):
            responses = [_linear(params, names, frequencies(fmin, fmax, points), args,
                                 _get(args, 'sampling', 'continuous'))]
            linear = None
        else:
            inp, out, loop, qty = names
            responses = simulated_response(
                params, inp, out, loop, qty, _get(args, 'method', 'sine'), fmin, fmax, points,
                amps, dt, _get(args, 'speed', 0.0), _get(args, 'mode'),
                _get(args, 'settle', 3), _get(args, 'periods', 5), _get(args, 'workers'),
                _get(args, 'scheduler'))
            linear = (_linear(params, names, frequencies(fmin, fmax, OVERLAY_POINTS), args,
                              'step', measurement_step(params, dt, names[2]))
                      if params.drive_type == 'servo' else None)    # a stepper: none
    if _get(args, 'output_csv'):
        write_csv(args.output_csv, responses)
    if _get(args, 'plot'):
        plot_bode(args.plot, responses, linear)
    return dict(responses=responses, linear=linear, lines=summary_lines(responses, linear))
