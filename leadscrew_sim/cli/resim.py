"""
``resim``: re-run the commands of a recording through the model and compare the states.

The re-simulation is :class:`leadscrew_sim.offline.replay.resim.Resim`: the node's
command rules, the model in blocks. The comparison decodes the recorded
states of each topic at once where their layout is the encoder's.
"""
import math
import os
from pathlib import Path

import numpy as np

from .args import add_compression_argument, add_mapping_arguments
from .event_lines import print_events
from ..offline.foreign.mapping import Mapping
from ..offline.foreign.twin import plot_twin, report_lines, twin_comparison
from ..offline.options import (compression_of, gc_paused, load_params, open_recording,
                               parse_sets, Progress, RunError)
from ..offline.replay.resim import Resim
from ..offline.run_events import EventLog
from ..core.params import ScrewParams
from ..io import cdr as C, messages as M
from ..io.run_file import CLI_RECORD, PARAMS_RECORD, RunWriter

HELP = 're-simulate a recording and compare'


def add_arguments(p):
    """Add the options of ``resim`` to parser ``p``."""
    p.add_argument('file', help='the recording (MCAP file or rosbag2 bag directory)')
    p.add_argument('--set', action='append', metavar='NAME=VALUE',
                   help='override a recorded physics parameter (repeatable; YAML scalar in '
                   'the parameter\'s unit)')
    p.add_argument('--output', '-o', metavar='FILE.mcap',
                   help='output MCAP (default <stem>.resim.mcap; a leadscrew_sim recording)')
    add_compression_argument(p)
    p.add_argument('--quiet', '-q', action='store_true', help='no progress bar')
    g = add_mapping_arguments(p)
    g.add_argument('--preset', help='the twin\'s parameters: a preset (a foreign recording)')
    g.add_argument('--params', help='the twin\'s parameters: a ROS 2 parameter file (a '
                   'foreign recording)')
    g.add_argument('--plot', metavar='FILE.png', help='measured vs twin over time (a foreign '
                   'recording)')


def compare(sim, new):
    """
    Return rows (topic, field, max |diff|, rms diff, n) of the new vs the recorded states.

    Also returns the number of compared values whose IEEE 754 bits differ (a
    zero difference can hide -0.0 against +0.0).

    Parameters
    ----------
    sim : Resim
        The re-simulation, with its recorded states.
    new : NewStates
        What :meth:`Resim.run` produced.

    """
    enc = M.StateEncoder(sim.prefix, sim.params.anti_backlash)
    screw, nut = sim.joint_labels()
    truth_plan = {topic: index for topic, _t, _s, index, _n in enc._plan['truth']}
    tables = [   # topic, field labels, recorded decoder, new values (n_steps + 1, m), has
        ('joint_states', [f'{q}[{j}]' for q in ('position', 'velocity', 'effort')
                          for j in (screw, nut)], _joint_states6, new.sensor,
         new.has_sensor),
        ('nut_position', ['data'], _float64s, new.sensor[:, [1]], new.has_sensor),
        ('thread_force', ['force.x', 'torque.x'], _wrench2, new.truth[:, [12, 9]],
         new.has_truth)]
    rows, bits = [], 0
    for topic, labels, decode, values, has in tables:
        got = _compared(sim, topic, decode, values, has)
        bits += _table_rows(rows, sim.topics.get(topic) or topic, labels, got)
    if 'sim/joint_states' in sim.states:
        index = list(truth_plan['sim/joint_states'])
        names, recorded = _truth_values(sim.states['sim/joint_states'][1])
        if names is not None:
            labels = [f'{q}[{name}]' for q in ('position', 'velocity', 'effort')
                      for name in names]
            ks = np.asarray(sim.states['sim/joint_states'][0])
            got = _pairs(ks, recorded, new.truth[:, index[:recorded.shape[1]]], new.has_truth)
            bits += _table_rows(rows, sim.topics.get('sim/joint_states'), labels, got)
    return rows, bits


def _compared(sim, topic, decode, values, has):
    """Return (recorded, new) value arrays of the steps where both have a state of a topic."""
    if topic not in sim.states:
        return None
    ks, datas = sim.states[topic]
    return _pairs(np.asarray(ks), decode(datas), values, has)


def _pairs(ks, recorded, values, has):
    """Return the recorded and the new values of the steps ``ks`` both have."""
    ks_in = ks < len(has)
    ok = np.zeros(len(ks), dtype=bool)
    ok[ks_in] = has[ks[ks_in]]
    if ok.all() and len(ks) and ks[-1] - ks[0] == len(ks) - 1 and (np.diff(ks) == 1).all():
        return recorded, values[ks[0]:ks[-1] + 1]       # every step of a stretch: views
    return recorded[ok], values[ks[ok]]


def _table_rows(rows, topic, labels, got):
    """Append a topic's rows (topic, field, max, rms, n); return its bit differences."""
    if got is None:
        return 0
    old, now = got
    d = np.abs(old - now)
    d[np.isnan(d)] = math.inf                   # a NaN on one side only, or on both
    n = len(d)
    bits = int(np.count_nonzero(old.view(np.int64) != now.view(np.int64)))
    if n:
        largest = d.max(axis=0)
        rms = np.sqrt(np.einsum('ij,ij->j', d, d) / n)
    for j, label in enumerate(labels):
        rows.append((topic, label, float(largest[j]) if n else 0.0,
                     float(rms[j]) if n else float('nan'), n))
    return bits


def _rows_of(datas):
    if isinstance(datas, np.ndarray):
        return datas
    lengths = {len(d) for d in datas}
    if len(lengths) != 1:
        return None
    return np.frombuffer(b''.join(datas), dtype=np.uint8).reshape(len(datas), -1)


def _joint_states6(datas):
    """Return (n, 6): the first two positions, velocities and efforts of each JointState."""
    rows = _rows_of(datas)
    if rows is not None:
        names = C.decode_joint_state(bytes(datas[0]))[1]
        got = C.joint_state_template(names, 2, 2, 2).columns(rows) if len(names) == 2 else None
        if got is not None:
            return got
    out = np.full((len(datas), 6), np.nan)
    for i, d in enumerate(datas):
        _s, _n, pos, vel, eff = C.decode_joint_state(bytes(d))
        for j, (a, b) in enumerate(((pos, 0), (pos, 1), (vel, 0), (vel, 1), (eff, 0),
                                    (eff, 1))):
            if len(a) > b:
                out[i, j] = a[b]
    return out


def _float64s(datas):
    """Return (n, 1): the data of each std_msgs/Float64."""
    return C.decode_float64s(datas).reshape(-1, 1)


def _wrench2(datas):
    """Return (n, 2): force.x and torque.x of each WrenchStamped."""
    rows = _rows_of(datas)
    got = C.wrench_template().columns(rows) if rows is not None else None
    if got is not None:
        return got
    out = [(f[0], t[0]) for _s, f, t in (C.decode_wrench_stamped(bytes(d)) for d in datas)]
    return np.array(out, dtype=float).reshape(-1, 2)


def _truth_values(datas):
    """Return (joint names, (n, 3 m) positions, velocities, efforts) of sim/joint_states."""
    if not len(datas):
        return None, None
    names = C.decode_joint_state(bytes(datas[0]))[1]
    m = len(names)
    rows = _rows_of(datas)
    got = C.joint_state_template(names, m, m, m).columns(rows) if rows is not None else None
    if got is None:
        got = np.full((len(datas), 3 * m), np.nan)
        for i, d in enumerate(datas):
            _s, nm, pos, vel, eff = C.decode_joint_state(bytes(d))
            if list(nm) == list(names) and len(pos) == len(vel) == len(eff) == m:
                got[i] = list(pos) + list(vel) + list(eff)
    return names, got


def run(args):
    """Re-simulate a recording and print the difference from the recorded states."""
    with gc_paused():
        return _run(args)


def _run(args):
    phys_ov, run_ov = parse_sets(args.set)
    if run_ov:
        raise RunError('resim --set accepts physics parameters only')
    rec = open_recording(args.file, load_messages=False)
    mapping = Mapping.from_args(args)
    if mapping.given or args.preset or args.params or rec.record(PARAMS_RECORD) is None:
        return _twin(args, rec, mapping, phys_ov)
    sim = Resim(rec, phys_ov)
    src = Path(args.file)
    out = args.output or str(src.with_name(src.name[:-5] if src.name.endswith('.mcap')
                                           else src.name)) + '.resim.mcap'
    if os.path.isdir(out):
        raise RunError(f'--output {out} is a directory')
    if os.path.abspath(out) == os.path.abspath(args.file):
        raise RunError(f'--output {out} would overwrite the input file')
    w = RunWriter(out, sim.prefix, params=sim.params, compression=compression_of(args))
    meta = dict(sim.meta)
    meta.update({n: str(getattr(sim.params, n)) for n in ScrewParams.names()})
    w.rec.add_metadata(PARAMS_RECORD, meta)
    w.rec.add_metadata(CLI_RECORD, {'command': 'resim', 'source': str(args.file),
                                    'overrides': ' '.join(args.set or [])})
    try:
        w.write_description(sim.t0)
        progress = Progress(sim.n_steps, 'resim', args.quiet)
        log = EventLog(sim.params, sim.dt_ns)
        new, _model = sim.run(w, progress=progress, log=log)
        compared = compare(sim, new)        # while the writer thread ends the file
    finally:
        w.close()
    _report(args, sim, out, new, compared)
    print_events(log.events())
    return 0


def _twin(args, rec, mapping, phys_ov):
    """Compare a foreign recording with its twin (``--preset``/``--params``); print, plot."""
    rec.require_ros2()
    if not (args.preset or args.params):
        raise RunError(f'{args.file}: not a leadscrew_sim recording: give the twin\'s '
                       'parameters (--preset NAME or --params FILE) and the mapping flags '
                       f'(`leadscrew_sim info {args.file}` prints those that fit)')
    params, label, _extra = load_params(args, phys_ov)
    comp = twin_comparison(rec, params, mapping)
    overrides = f' ({" ".join(args.set)})' if args.set else ''
    for line in report_lines(comp, f' with {label}{overrides}'):
        print(line)
    if args.plot:
        plot_twin(comp, args.plot)
        print(f'wrote {args.plot}')
    return 0


def _report(args, sim, out, new, compared):
    """Print the summary and the difference table (``compare``'s result) of a resim run."""
    rows, bit_differences = compared
    print(f'resim of {args.file}: {sim.n_steps} steps at dt {sim.dt_ns} ns '
          f'(clock_mode {sim.clock_mode or "?"}), overrides: '
          f'{" ".join(args.set or []) or "none"}; wrote {out}')
    if sim.missing:
        print(f'warning: parameters missing from the recording (defaults used): '
              f'{", ".join(sim.missing)}')
    if sim.clock_mode == 'realtime':
        print('note: realtime recording: command timeouts were wall-clock based and '
              'overrun skips are not reproduced')
    print(f'{"topic":<24} {"field":<24} {"max |diff|":>14} {"rms diff":>14} {"n":>8}')
    overall = 0.0
    for topic, field, mx, rms, n in rows:
        print(f'{topic:<24} {field:<24} {float(mx)!r:>14} {float(rms)!r:>14} {n:>8}')
        if n:
            overall = max(overall, float(mx))
    has = new.has_sensor | new.has_truth
    recorded = np.zeros(len(has), dtype=bool)
    for ks, _d in sim.states.values():
        ks = np.asarray(ks, dtype=np.int64)
        recorded[ks[ks < len(has)]] = True
    compared = int(np.count_nonzero(recorded & has))
    note = ''
    if compared and overall == 0.0:
        note = (' (bit-identical)' if not bit_differences else
                f' (equal values, but {bit_differences} differ in their bits: -0.0/+0.0)')
    print(f'compared {compared} recorded ticks; overall max |diff|: {overall!r}{note}')
