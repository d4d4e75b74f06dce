"""
The ``commission`` run: one recording through every stage, then fit.yaml, report.json, report.html.

The stages run in order, each timed and announced on stderr: identify (the
friction on the sweep), the twin (the calibrated re-simulation judged on
the parts after the sweep), friction, backlash, frequency response,
stability, ISO 230-2 and the stepper's pull-out. A part the recording lacks
leaves its figures out and says what it would add.
"""
import json
import math
import os
import sys
import tempfile
import time

from .context import Context
from .segments import check_span, find_segments, missing
from .sources import open_axis
from ..foreign.mapping import Mapping
from ..foreign.replay import own_command_specs
from .stages import backlash, fit, friction, iso230, response, stability, stepper, twin
from . import html, views
from ..identify.inputs import start_params
from ..identify.output import params_document, write_text
from ..options import NS, open_recording, option_text, RunError
from ...io.run_file import PARAMS_RECORD

#: (name, function) of the stages in their order.
STAGES = (('identify', fit.run), ('twin', twin.run), ('friction', friction.run),
          ('backlash', backlash.run), ('frequency response', response.run),
          ('stability', stability.run), ('iso230', iso230.run), ('stepper', stepper.run))


def _say(line):
    print(line, file=sys.stderr, flush=True)


def commission(path, out_dir, identify_args, sidecar=None, progress=_say, keep=None,
               name_of=None):
    """
    Commission the axis of recording ``path``; write DIR's three files; return the report dict.

    Parameters
    ----------
    path : str
        The recording: a leadscrew_sim MCAP file, or a real axis's rosbag2 bag
        (or ros2 MCAP file) with the mapping options in ``identify_args``.
    out_dir : str
        Where fit.yaml, report.json and report.html go (created).
    identify_args : argparse.Namespace
        The options of ``identify`` (starting values, mapping flags); ``file``
        and ``fit`` are set here.
    sidecar : str, optional
        A segments sidecar JSON file.
    progress : callable
        Gets one line per stage (stderr).
    keep : dict, optional
        Gets ``fit``: what the fit stage's :func:`fit_recording` returned
        (None: no fit).
    name_of : callable, optional
        ``name_of(keyword)``: the name of an option the report and fit.yaml
        name (default its keyword; :func:`..options.option_text`).

    """
    t_all = time.perf_counter()
    rec = open_recording(path)
    rec.require_ros2()
    if rec.record(PARAMS_RECORD) is None and not Mapping.from_args(identify_args).given \
            and not own_command_specs(rec):
        raise RunError(f'{path}: does not map to an axis: no "{PARAMS_RECORD}" record and no '
                       'mapping (a bag of another stack needs <<command_topic>> and the joints, '
                       f'or <<map>> FILE.yaml; `leadscrew_sim info {path}` prints the flags '
                       'that fit it)')
    start, label = start_params(identify_args, rec)
    axis = open_axis(rec, identify_args, start)
    commands = axis.commands
    st = rec.statistics()
    duration = (st.message_end_time - st.message_start_time) / NS if st and st.message_count \
        else 0.0
    windows, source = find_segments(rec, commands, sidecar)
    if not windows:
        raise RunError(f'{path}: no commission part found in its commands ({duration:.3g} s); '
                       'record `leadscrew_sim excite commission`')
    check_span(windows, duration)
    origin = _origin(st)
    windows = {n: (a - origin, b - origin) for n, (a, b) in windows.items()}
    commands = {k: (ts - origin, vs) for k, (ts, vs) in commands.items()}
    axis.measured.time = axis.measured.time - origin
    try:
        os.makedirs(out_dir, exist_ok=True)
    except OSError as exc:
        raise RunError(f'<<output>> {out_dir}: {exc.strerror or exc}') from None
    timings = {}
    with tempfile.TemporaryDirectory(prefix='commission_') as work:
        ctx = Context(path=str(path), rec=rec, windows=windows, commands=commands,
                      measured=axis.measured, start=start, label=label, work=work,
                      identify_args=identify_args, calibrated=start, axis=axis,
                      origin=origin)
        ctx.rate = axis.rate
        sections = {}
        for i, (name, fn) in enumerate(STAGES):
            t0 = time.perf_counter()
            progress(f'commission: [{i + 1}/{len(STAGES)}] {name} ...')
            sections[name] = fn(ctx, progress) if fn is fit.run else fn(ctx)
            timings[name] = time.perf_counter() - t0
            progress(f'commission: [{i + 1}/{len(STAGES)}] {name} done in '
                     f'{timings[name]:.2f} s')
    sections = {'axis': _axis(ctx, duration, source), **sections}
    sections['undetermined'] = _undetermined(sections)
    report = {'format': 'leadscrew_sim.commission/1', 'recording': str(path),
              'time_origin_s': origin,
              'sections': _named(_clean(sections), name_of), 'timings_s': timings,
              'wall_s': time.perf_counter() - t_all, 'fitted_on': ctx.fitted_on}
    if keep is not None:
        keep['fit'] = getattr(ctx, 'fit', None)
    _write_fit(os.path.join(out_dir, 'fit.yaml'), ctx, name_of)
    write_text(os.path.join(out_dir, 'report.json'), json.dumps(report, indent=1) + '\n', 'output')
    page = html.render(f'Commissioning report: {os.path.basename(str(path))}',
                       f'preset {label}; {duration:.1f} s recorded; segments from {source}',
                       _named(views.sections(ctx, report['sections']), name_of))
    write_text(os.path.join(out_dir, 'report.html'), page, 'output')
    report['wall_s'] = time.perf_counter() - t_all
    progress(f'commission: wrote {out_dir}/fit.yaml, report.json, report.html in '
             f'{report["wall_s"]:.1f} s')
    return report


#: Log times past this [s] are a wall clock's (epoch): the report counts from the start.
EPOCH_S = 1e6


def _origin(st):
    """Return the time [s] the report's times count from: 0, or an epoch recording's start."""
    if st is None or not st.message_count:
        return 0.0
    start = st.message_start_time / NS
    return float(start) if start > EPOCH_S else 0.0


def _axis(ctx, duration, source):
    s = ctx.start
    sensors, sensors_from = ctx.axis.sensors(s, ctx.fit)
    out = {'title': 'The axis and the recording', 'preset': ctx.label,
           'drive_type': s.drive_type, 'sensors': sensors, 'sensors_from': sensors_from,
           'duration_s': duration, 'segments': {n: list(w) for n, w in ctx.windows.items()},
           'segments_source': source,
           'missing': [{'part': n, 'would_add': w} for n, w in missing(ctx.windows)
                       if not (n == 'breakaway' and s.drive_type == 'stepper')],
           'cannot': []}
    if ctx.axis.foreign:
        rep = ctx.axis.replay
        out['mapping'] = {'state_topic': rep.state_topic, 'command_topic': rep.command_topic,
                          'command_type': rep.commands.ctype, 'joints': list(rep.joints),
                          'step_rate_hz': ctx.rate, 'command_delay_s': rep.delay.value}
        if ctx.axis.nut_from_screw:
            out['cannot'].append('the states carry no nut joint: the nut position is the '
                                 'screw angle through the lead (backlash and the flanks do '
                                 'not show in it)')
    return out


def _undetermined(sections):
    lines = []
    for key, sec in sections.items():
        if sec is None:
            continue
        for c in sec.get('cannot', []):
            lines.append(f'{sec.get("title", key)}: {c}')
    for m in sections['axis']['missing']:
        lines.append(f'missing segment {m["part"]}: it would add {m["would_add"]}')
    return {'title': 'What could not be determined', 'lines': lines}


def _clean(x):
    """Return ``x`` with NaN and infinities as None (JSON)."""
    if isinstance(x, dict):
        return {str(k): _clean(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_clean(v) for v in x]
    if isinstance(x, float):
        return x if math.isfinite(x) else None
    if hasattr(x, 'item') and not isinstance(x, (str, bytes)):
        return _clean(x.item())
    return x


def _named(x, name_of):
    """Return ``x`` with each text's options (``<<keyword>>``) named by ``name_of``."""
    if isinstance(x, str):
        return option_text(x, name_of)
    if isinstance(x, dict):
        return {k: _named(v, name_of) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return type(x)(_named(v, name_of) for v in x)
    return x


def _write_fit(path, ctx, name_of=None):
    if ctx.fit is None:
        text = (f'# leadscrew_sim commission: nothing identified (no sweep); the starting '
                f'values came from {ctx.label}\n/**:\n  ros__parameters: {{}}\n')
    else:
        text = params_document(ctx.fit['params'], ctx.label, ctx.fit['res'], name_of=name_of)
        text = text.replace('# leadscrew_sim identify:', '# leadscrew_sim commission (identify '
                            'on the sweep):', 1)
    fitted = getattr(ctx, 'backlash_fit', None)
    if fitted is not None:
        value, lower, upper = fitted
        line = (f'    backlash: {value!r}  # commission: fitted on the reversals, 95 % '
                f'interval [{lower:.6g}, {upper:.6g}] m')
        text = text.rstrip('\n') + '\n' + line + '\n'
    write_text(path, text, 'output')
