"""
``resim``: re-run the commands of a recording through the model and compare the states.

The commands go through :class:`leadscrew_sim.core.commands.CommandHold`,
the node's rules (validation, zero-order hold, timeout), and act on the steps
:data:`~leadscrew_sim.core.commands.COMMAND_LOG_TIME` says; ``info`` and
``plot`` re-simulate through :class:`Resim` too.
"""
import math
import os
from pathlib import Path
import struct

from .args import CliError, NS, parse_sets, Progress
from ..core.commands import CommandHold, DROPPED, JOINT_COMMAND_MODES, NutMap, REJECTED
from ..core.delivery import StateDelivery
from ..core.params import ParameterError, ScrewParams
from ..io import cdr as C, messages as M, topics as T
from ..io.mcap_reader import Recording
from ..io.run_file import (CLEAR_FAULT_RECORD, CLI_RECORD, PARAMS_RECORD, params_from_record,
                           RESET_RECORD, run_setting, RunWriter, UPDATE_RECORD)

HELP = 're-simulate a recording and compare'


def add_arguments(p):
    """Add the options of ``resim`` to parser ``p``."""
    p.add_argument('file')
    p.add_argument('--set', action='append', metavar='NAME=VALUE')
    p.add_argument('--output', '-o', help='output MCAP (default <stem>.resim.mcap)')
    p.add_argument('--quiet', '-q', action='store_true')


class Resim:
    """
    Re-run a leadscrew_sim recording through the model.

    Commands (torque_command, joint_commands effort of the screw joint,
    external_force), parameter updates and resets are applied in log-time
    order: everything logged at or before ``t0 + k dt`` acts on step k (the
    node's rule); torque commands older than ``command_timeout`` (sim time)
    become 0 as in the node's stepped and lockstep modes. States are produced
    at ``t0 + (k + 1) dt`` every ``publish_decimation`` steps.

    A reset or parameter update logged at the same time as messages takes its
    place among them from ``messages_at_log_time`` (the number of messages of
    that log time the node recorded before it; the file order of the messages
    is their recording order). Without that key it comes after them.

    Parameters
    ----------
    rec : Recording
        A leadscrew_sim recording with its messages.
    phys_overrides : dict, optional
        Physics parameters replacing the recorded ones (also in every update).

    """

    def __init__(self, rec, phys_overrides=None):
        """Read parameters, run settings, commands and recorded states from ``rec``."""
        rec.require_ours('resim')
        meta = rec.record(PARAMS_RECORD)
        self.rec = rec
        self.meta = meta
        self.overrides = dict(phys_overrides or {})
        try:
            params, self.missing = params_from_record(meta)
        except ParameterError as exc:
            raise CliError(f'{rec.path}: recorded {exc}') from None
        self.params = ScrewParams.from_dict(self.overrides, base=params) \
            if self.overrides else params
        try:
            rate = float(run_setting(meta, 'update_rate', 1000.0))
            self.dt_ns = int(meta.get('dt_ns') or round(NS / rate))
            self.t0 = int(meta.get('t0_ns', 0))
            self.decimation = max(1, run_setting(meta, 'publish_decimation', 1))
            self.timeout = run_setting(meta, 'command_timeout', 0.0)
        except ValueError as exc:
            raise CliError(f'{rec.path}: bad run settings in the parameters record: '
                           f'{exc}') from None
        self.prefix = run_setting(meta, 'joint_prefix', '')
        self.joint_command_mode = run_setting(meta, 'joint_command_mode', 'auto')
        self.clock_mode = run_setting(meta, 'clock_mode', '')
        self.topics = {rel: rec.role_topic(rel) for rel in T.COMMAND_TOPICS + T.STATE_TOPICS}
        self.events = []            # (log_time [ns], kind, payload) in log-time order
        self.states = {}            # step index -> dict(rel -> bytes)
        order = self._read_messages()
        order += self._read_records()
        index = sorted(range(len(self.events)), key=order.__getitem__)
        self.events = [self.events[i] for i in index]
        last_state = max(self.states, default=-1)
        if last_state < 0:
            last_cmd = max([(e[0] - self.t0) // self.dt_ns for e in self.events] or [-1])
            last_state = last_cmd + 1
        self.n_steps = max(0, last_state)

    def _read_messages(self):
        """Collect the commands and the recorded states; return the commands' sort keys."""
        by_topic = {t: rel for rel, t in self.topics.items() if t}
        order = []                  # (log time, rank among the messages of that log time)
        same_t, rank = None, 0
        for log_time, topic, data in self.rec.messages:
            if log_time != same_t:
                same_t, rank = log_time, 0
            rank += 1
            rel = by_topic.get(topic)
            if rel in T.COMMAND_TOPICS:
                self.events.append((log_time, rel, data))
                order.append((log_time, rank))
            elif rel in T.STATE_TOPICS:
                k, r = divmod(log_time - self.t0, self.dt_ns)
                if r == 0 and k > 0:
                    self.states.setdefault(k, {})[rel] = data
        return order

    def _read_records(self):
        """Collect the parameter updates and resets; return their sort keys."""
        order = []
        for name, data in self.rec.metadata:
            if name in (UPDATE_RECORD, RESET_RECORD, CLEAR_FAULT_RECORD) and 'log_time_ns' in data:
                try:
                    log_time = int(data['log_time_ns'])
                    before = int(data.get('messages_at_log_time', -1))
                except ValueError as exc:
                    raise CliError(f'{self.rec.path}: bad "{name}" metadata record: '
                                   f'{exc}') from None
                self.events.append((log_time, name, data))
                # after the first `before` messages of its log time; else after all
                order.append((log_time, before + 0.5 if before >= 0 else math.inf))
        return order

    def run(self, writer=None, keep=False, progress=None):
        """
        Run all steps; optionally write a new recording and keep per-step outputs.

        Returns (new states {k: (js values, x, wrench values)}, outputs list or None,
        model).
        """
        from ..core.model import LeadScrewModel
        model = LeadScrewModel(self.params, dt=self.dt_ns / NS)
        hold = CommandHold(self.prefix, self.timeout if self.clock_mode != 'realtime' else 0.0,
                           NutMap.of_model(model), self.joint_command_mode, model.params)
        line = self.line = StateDelivery(model.params)
        events, ne, ie = self.events, len(self.events), 0
        dt_ns, t0, dec = self.dt_ns, self.t0, self.decimation
        new_states = {}
        outs = [] if keep else None
        enc = M.StateEncoder(self.prefix, self.params.anti_backlash)
        self.rejected = 0
        for k in range(self.n_steps):
            t_k = t0 + k * dt_ns
            while ie < ne and events[ie][0] <= t_k:
                log_time, kind, data = events[ie]
                ie += 1
                if writer is not None and kind in writer.ids:
                    writer.write(writer.ids[kind], data, log_time)
                self._apply(kind, data, t_k, hold, model, line)
            command = hold.changed_command(t_k)
            if command is not None:
                model.command(*command)
            try:
                model.advance_held(hold.force)
            except FloatingPointError as exc:
                raise CliError(f'simulation fault at step {k}: {exc}') from None
            if (k + 1) % dec == 0:
                line.sample(k + 1, t_k + dt_ns, model.joint_values())
            sampled = (k + 1) % dec == 0
            _states(line.due(k + 1), model.truth_values() if sampled else None,
                    t_k + dt_ns, writer, enc, new_states, self.dt_ns, t0,
                    model.analysis_values() if sampled and writer is not None else None)
            if keep:
                outs.append(model.output())
            if progress is not None and not k & 1023:
                progress.update(k)
        if progress is not None:
            progress.done()
        return new_states, outs, model

    def _apply(self, kind, data, t_k, hold, model, line):
        """Apply one event at step time ``t_k`` [ns]; count the rejected commands."""
        if kind == 'torque_command':
            self.rejected += hold.torque_command(C.decode_float64(data), t_k) not in (
                None, DROPPED)
        elif kind == 'velocity_command':
            self.rejected += hold.velocity_command(C.decode_float64(data), t_k) not in (
                None, DROPPED)
        elif kind == 'position_command':
            self.rejected += hold.position_command(C.decode_float64(data), t_k) not in (
                None, DROPPED)
        elif kind == 'joint_commands':
            _s, names, pos, vel, eff = C.decode_joint_state(data)
            self.rejected += hold.joint_commands(names, pos, vel, eff, t_k)[0] == REJECTED
        elif kind == 'external_force':
            self.rejected += hold.external_force(C.decode_float64(data)) is not None
        elif kind == UPDATE_RECORD:
            # the overrides are in model.params already: keep them
            changes = {n: v for n, v in data.items() if n not in self.overrides}
            try:
                params = ScrewParams.from_text(changes, base=model.params)
            except ParameterError as exc:
                raise CliError(f'{self.rec.path}: recorded {exc}') from None
            model.set_params(params)
            hold.set_faults(params)
            line.set_faults(params)
            if 'command_timeout' in data and self.clock_mode != 'realtime':
                hold.timeout = run_setting(data, 'command_timeout', hold.timeout)
            if 'joint_command_mode' in data:
                hold.joint_mode = JOINT_COMMAND_MODES[run_setting(data, 'joint_command_mode',
                                                                  'auto')]
        elif kind == RESET_RECORD:
            model.reset()
            hold.reset()
            line.reset()
            hold.nut_map = NutMap.of_model(model)
        elif kind == CLEAR_FAULT_RECORD:
            model.clear_fault()

    def compare(self, new_states):
        """
        Return rows (topic, field, max |diff|, rms diff, n) of new vs recorded states.

        Also sets ``bit_differences``: the number of compared values whose IEEE 754
        bits differ (a zero difference can hide -0.0 against +0.0).
        """
        fields = [('joint_states', f'{q}[{j}]') for q in ('position', 'velocity', 'effort')
                  for j in self.joint_labels()] + [('nut_position', 'data'),
                                                   ('thread_force', 'force.x'),
                                                   ('thread_force', 'torque.x')]
        acc = {f: [0.0, 0.0, 0, 0] for f in fields}
        for k, rec in self.states.items():
            new = new_states.get(k)
            if new is None:
                continue
            js, x, wr, truth = new
            if 'sim/joint_states' in rec and truth is not None:
                self._compare_truth(acc, rec['sim/joint_states'], truth)
            if 'joint_states' in rec and js is not None:
                _s, _n, pos, vel, eff = C.decode_joint_state(rec['joint_states'])
                old = list(pos[:2]) + list(vel[:2]) + list(eff[:2])
                for i, (field, val) in enumerate(zip(fields[:6], old)):
                    _acc(acc[field], val, js[i])
            if 'nut_position' in rec and x is not None:
                _acc(acc[fields[6]], C.decode_float64(rec['nut_position']), x)
            if 'thread_force' in rec and wr is not None:
                _s, f, t = C.decode_wrench_stamped(rec['thread_force'])
                _acc(acc[fields[7]], f[0], wr[0])
                _acc(acc[fields[8]], t[0], wr[1])
        rows = []
        self.bit_differences = sum(a[3] for a in acc.values())
        fields += [f for f in acc if f not in fields]      # sim/joint_states, as recorded
        for topic, field in fields:
            mx, sq, n, _bits = acc[topic, field]
            rows.append((self.topics.get(topic) or topic, field, mx,
                         math.sqrt(sq / n) if n else float('nan'), n))
        return rows

    @staticmethod
    def _compare_truth(acc, recorded, new):
        """Accumulate the differences of a recorded and a new sim/joint_states message."""
        _s, names, *old = C.decode_joint_state(recorded)
        _s, _names, *now = C.decode_joint_state(new)
        for q, a, b in zip(('position', 'velocity', 'effort'), old, now):
            for name, va, vb in zip(names, a, b):
                _acc(acc.setdefault(('sim/joint_states', f'{q}[{name}]'), [0.0, 0.0, 0, 0]),
                     va, vb)

    def joint_labels(self):
        """Return the two joint names."""
        return (self.prefix + 'screw_joint', self.prefix + 'nut_joint')


def _states(delivered, truth, now, writer, enc, new_states, dt_ns, t0, analysis=None):
    """
    Keep (and write, if asked) the states of one tick, as the node publishes them.

    ``delivered``: the [(stamp, sensor values)] due at ``now`` [ns]; ``truth``: the
    truth values of a sampled tick (None otherwise). ``new_states`` gets, per
    step index of ``now`` (the log time, as the recorded states are indexed),
    [joint_states values, nut position, thread force values, sim/joint_states
    bytes], None where the tick published none. ``analysis``: the tick's
    analysis values, written after the truth (None: none).
    """
    values = None
    for stamp, values in delivered:
        if writer is not None:
            for topic, data in enc.sensor(stamp, values):
                writer.write(writer.ids[topic], data, now)
        new_states.setdefault((now - t0) // dt_ns, [None] * 4)[:2] = values, values[1]
    if truth is not None:
        messages = enc.truth(now, truth)
        if writer is not None:
            for topic, data in messages:
                writer.write(writer.ids[topic], data, now)
        new_states.setdefault((now - t0) // dt_ns, [None] * 4)[2:] = \
            (truth[-1], truth[9]), dict(messages)['sim/joint_states']
    if analysis is not None:
        for topic, data in enc.analysis(now, analysis):
            writer.write(writer.ids[topic], data, now)
    if values is not None and writer is not None:
        writer.write_tf(stamp, values[0], values[1], now)


_BITS = struct.Struct('<d').pack


def _acc(a, old, new):
    """Accumulate max |diff|, sum of squares, count and bit differences of one value."""
    d = old - new
    d = abs(d) if d == d else math.inf
    if d > a[0]:
        a[0] = d
    a[1] += d * d
    a[2] += 1
    if d or _BITS(old) != _BITS(new):
        a[3] += 1


def run(args):
    """Re-simulate a recording and print the difference from the recorded states."""
    phys_ov, run_ov = parse_sets(args.set)
    if run_ov:
        raise CliError('resim --set accepts physics parameters only')
    rec = Recording(args.file)
    sim = Resim(rec, phys_ov)
    src = Path(args.file)
    out = args.output or str(src.with_name(src.name[:-5] if src.name.endswith('.mcap')
                                           else src.name)) + '.resim.mcap'
    if os.path.abspath(out) == os.path.abspath(args.file):
        raise CliError(f'--output {out} would overwrite the input file')
    w = RunWriter(out, sim.prefix, params=sim.params)
    meta = dict(sim.meta)
    meta.update({n: str(getattr(sim.params, n)) for n in ScrewParams.names()})
    w.rec.add_metadata(PARAMS_RECORD, meta)
    w.rec.add_metadata(CLI_RECORD, {'command': 'resim', 'source': str(args.file),
                                    'overrides': ' '.join(args.set or [])})
    try:
        w.write_description(sim.t0)
        progress = Progress(sim.n_steps, 'resim', args.quiet)
        new_states, _outs, _model = sim.run(w, progress=progress)
    finally:
        w.close()
    _report(args, sim, out, new_states)
    return 0


def _report(args, sim, out, new_states):
    """Print the summary and the difference table of a resim run."""
    rows = sim.compare(new_states)
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
    compared = sum(1 for k in sim.states if k in new_states)
    note = ''
    if compared and overall == 0.0:
        note = (' (bit-identical)' if not sim.bit_differences else
                f' (equal values, but {sim.bit_differences} differ in their bits: -0.0/+0.0)')
    print(f'compared {compared} recorded ticks; overall max |diff|: {overall!r}{note}')
