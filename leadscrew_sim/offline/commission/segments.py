"""
Where the parts of a commissioning run lie in a recording: its record, a sidecar, or its commands.

Three sources, in this order:

- the segments record (:data:`SEGMENTS_RECORD`) that ``simulate`` writes
  with the excite profile commission: names and [start, end] log times [s];
- a sidecar JSON file (the ``segments`` option, else ``RUN.segments.json``
  beside the recording) that ``excite commission`` writes (its ``segments``)
  for a recording without markers (a node's or ``ros2 bag record``'s):
  ``{"format": "leadscrew_sim.segments/1", "start_ns": <system time of the
  first command>, "segments": {"sweep": [0.0, 19.5], ...}}``, times [s]
  from the first command; they are placed at ``start_ns`` when the
  recording's log times span it, else at the first command recorded;
- the commands themselves: runs of messages on one command topic, a
  velocity run with few distinct values a sweep, with many a chirp, a
  torque run a breakaway, a small position run reversals, a large one
  ISO 230-2.
"""
import json
import math

import numpy as np

from ..options import NS, RunError
from ...analysis.excitation.commission import PART_ORDER, SEGMENTS_FORMAT, SEGMENTS_RECORD
from ...io import cdr as C

__all__ = ['KINDS', 'WHAT_EACH_ADDS', 'command_series', 'find_segments', 'write_sidecar']

#: Part -> command kind.
KINDS = {'sweep': 'velocity', 'breakaway': 'torque', 'reversals': 'position',
         'chirp': 'velocity', 'iso230': 'position'}
#: Part -> what the report gets from it (said for a missing part).
WHAT_EACH_ADDS = {
    'sweep': 'the friction fit (mu_s, mu_k, Stribeck velocity), the Stribeck points and '
             'the efficiencies',
    'breakaway': 'the breakaway torques each way (static friction seen directly)',
    'reversals': 'the reversal hysteresis (backlash) and a held-out part for the twin',
    'chirp': 'the measured frequency response (H1, coherence) over the linear model',
    'iso230': 'the ISO 230-2 bidirectional positioning figures',
}
#: Shortest run of commands on one topic taken as a part [s].
MIN_PART = 1.0


def write_sidecar(path, profile, start_ns):
    """
    Write the segments sidecar of a commission profile sent from ``start_ns`` [ns, system time].

    Parameters
    ----------
    path : str
        The JSON file.
    profile : Commission
        What was sent.
    start_ns : int
        System time of the first command [ns].

    """
    doc = {'format': SEGMENTS_FORMAT, 'start_ns': int(start_ns),
           'time_base': 'seconds from the first command',
           'segments': {n: [a, b] for n, a, b in profile.windows()}}
    try:
        with open(path, 'w') as fh:
            json.dump(doc, fh, indent=1)
            fh.write('\n')
    except OSError as exc:
        raise RunError(f'<<segments>> {path}: {exc.strerror or exc}') from None


def command_series(rec):
    """Return {kind: (log times [s], values)} of the recording's Float64 commands."""
    out = {}
    for kind in ('torque', 'velocity', 'position'):
        topic = rec.role_topic(f'{kind}_command')
        ts, vs = [], []
        if topic:
            for t, tp, data in rec.messages:
                if tp == topic:
                    ts.append(t / NS)
                    vs.append(C.decode_float64(data))
        out[kind] = (np.array(ts), np.array(vs))
    return out


def find_segments(rec, commands, sidecar=None):
    """
    Return ({part: (start [s], end [s])} in time order, where they came from).

    Parameters
    ----------
    rec : Recording
        The recording (its metadata and messages).
    commands : dict
        :func:`command_series` of it.
    sidecar : str, optional
        A sidecar JSON file (else ``RUN.segments.json`` if it exists).

    """
    record = rec.record(SEGMENTS_RECORD)
    if record:
        return _from_record(rec.path, record), f'the recording\'s {SEGMENTS_RECORD} record'
    import os
    path = sidecar or (str(rec.path) + '.segments.json')
    if sidecar or os.path.exists(path):
        return _from_sidecar(path, rec, commands), f'the sidecar {path}'
    return _inferred(commands), 'the recorded commands (no segments record nor sidecar)'


def _from_record(path, record):
    out = {}
    for name in record.get('names', '').split(','):
        if name in record:
            try:
                a, b = (float(x) for x in record[name].split())
            except ValueError:
                raise RunError(f'{path}: bad {SEGMENTS_RECORD} entry {name}='
                               f'{record[name]!r} (want "start end" in s)') from None
            out[name] = (a, b)
    return out


def _from_sidecar(path, rec, commands):
    try:
        with open(path) as fh:
            doc = json.load(fh)
    except OSError as exc:
        raise RunError(f'<<segments>> {path}: {exc.strerror or exc}') from None
    except ValueError as exc:
        raise RunError(f'<<segments>> {path}: not JSON ({exc})') from None
    if not isinstance(doc, dict) or doc.get('format') != SEGMENTS_FORMAT or not isinstance(
            doc.get('segments'), dict):
        raise RunError(f'<<segments>> {path}: not a segments file (want "format": '
                       f'"{SEGMENTS_FORMAT}" and a "segments" object)')
    firsts = [ts[0] for ts, _v in commands.values() if len(ts)]
    if not firsts:
        raise RunError(f'{rec.path}: no commands recorded to place the segments of {path} on')
    st = rec.statistics()
    t0 = min(firsts)
    start = doc.get('start_ns')
    if isinstance(start, (int, float)) and st is not None and \
            st.message_start_time <= start <= st.message_end_time:
        t0 = start / NS
    out = {}
    for name, span in doc['segments'].items():
        if name not in KINDS or not (isinstance(span, list) and len(span) == 2):
            raise RunError(f'<<segments>> {path}: bad segment {name!r}: {span!r} (want one of '
                           f'{", ".join(KINDS)} with [start, end] in s)')
        out[name] = (t0 + float(span[0]), t0 + float(span[1]))
    return dict(sorted(out.items(), key=lambda kv: kv[1][0]))


def _inferred(commands):
    """Return the parts found in the runs of commands on one topic."""
    events = sorted((t, kind, v) for kind, (ts, vs) in commands.items()
                    for t, v in zip(ts.tolist(), vs.tolist()))
    runs = []
    for t, kind, v in events:
        if runs and runs[-1][0] == kind:
            runs[-1][2] = t
            runs[-1][3].append(v)
        else:
            runs.append([kind, t, t, [v]])
    out = {}
    for kind, a, b, values in runs:
        if b - a < MIN_PART:
            continue
        v = np.asarray(values)
        if kind == 'torque':
            name = 'breakaway'
        elif kind == 'velocity':
            name = 'sweep' if len(np.unique(v)) < 0.05 * len(v) else 'chirp'
        else:
            name = 'iso230' if np.ptp(v) > 5e-3 else 'reversals'
        if name not in out:
            out[name] = (a, b)
    return dict(sorted(out.items(), key=lambda kv: kv[1][0]))


def missing(found):
    """Return [(part, what it would add)] of the parts not in ``found`` (iso230 optional)."""
    return [(n, WHAT_EACH_ADDS[n]) for n in PART_ORDER if n not in found]


def check_span(found, duration):
    """Raise RunError when no part lasts a second (the recording is too short to commission)."""
    if not any(b - a >= MIN_PART for a, b in found.values()) or not duration > MIN_PART:
        raise RunError(f'the recording is too short to commission ({duration:.3g} s, no part '
                       f'of {MIN_PART:g} s; record `leadscrew_sim excite commission`)')
    if any(not (math.isfinite(a) and math.isfinite(b) and b > a) for a, b in found.values()):
        raise RunError('the segments have a start after their end')
