"""
Re-simulation of a recording: its commands through the model, in blocks.

The commands go through :class:`leadscrew_sim.core.commands.CommandHold`,
the node's rules (validation, zero-order hold, timeout, delay and loss), and
act on the steps :data:`~leadscrew_sim.core.commands.COMMAND_LOG_TIME` says.
That pass gives the drive command row of every step (:meth:`Resim.inputs`);
the model then runs each stretch between parameter updates, resets and
fault clearings in one compiled call. ``resim``, ``info``, ``plot`` and
``identify`` re-simulate through :class:`Resim`.
"""
import math

import numpy as np

from ..options import NS, RunError, simulation_faults
from .events import RecordedEvents
from .inputs import CommandPass, MODEL_EVENTS, Segment
from ...core.delivery import StateDelivery
from ...core.params import ParameterError, ScrewParams
from ...io import messages as M, topics as T
from ...io.record_fill import Stamps
from ...io.run_file import (ageing_from_record, CLEAR_FAULT_RECORD, PARAMS_RECORD,
                            params_from_record, RELUBRICATE_RECORD, RESET_RECORD,
                            run_setting, UPDATE_RECORD)
from ...io.tick_writer import Events, Stream, write_block

#: Steps per part of a segment when writing: the model runs a part while the writer's
#: thread compresses the one before.
BLOCK_TICKS = 3000


class Resim:
    """
    Re-run a leadscrew_sim recording through the model.

    Commands (torque, velocity and position commands, joint_commands,
    external_force), parameter updates and resets are applied in log-time
    order: everything logged at or before ``t0 + k dt`` acts on step k (the
    node's rule); commands older than ``command_timeout`` (sim time) time out
    as in the node's stepped and lockstep modes. States are produced at
    ``t0 + (k + 1) dt`` every ``publish_decimation`` steps.

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
            raise RunError(f'{rec.path}: recorded {exc}') from None
        self.params = ScrewParams.from_dict(self.overrides, base=params) \
            if self.overrides else params
        try:        # the axis's ageing at the recording's start (None: a new axis)
            self.ageing = ageing_from_record(meta)
        except ParameterError as exc:
            raise RunError(f'{rec.path}: recorded {exc}') from None
        try:
            rate = float(run_setting(meta, 'update_rate', 1000.0))
            self.dt_ns = int(meta.get('dt_ns') or round(NS / rate))
            self.t0 = int(meta.get('t0_ns', 0))
            self.decimation = max(1, run_setting(meta, 'publish_decimation', 1))
            self.timeout = run_setting(meta, 'command_timeout', 0.0)
        except ValueError as exc:
            raise RunError(f'{rec.path}: bad run settings in the parameters record: '
                           f'{exc}') from None
        self.prefix = run_setting(meta, 'joint_prefix', '')
        self.joint_command_mode = run_setting(meta, 'joint_command_mode', 'auto')
        self.clock_mode = run_setting(meta, 'clock_mode', '')
        self.topics = {rel: rec.role_topic(rel) for rel in T.COMMAND_TOPICS + T.STATE_TOPICS}
        self.events = RecordedEvents()  # (log_time [ns], kind, payload) in log-time order
        self.states = {}            # rel -> (step indices, messages) of the recorded states
        self._read_messages()
        self._read_records()
        self.events.sort()          # by log time, then rank (stable: file order)
        last_state = max((int(ks[-1]) for ks, _d in self.states.values() if len(ks)),
                         default=-1)
        if last_state < 0:
            times = self.events.times
            last_cmd = int((times.max() - self.t0) // self.dt_ns) if len(times) else -1
            last_state = last_cmd + 1
        self.n_steps = max(0, last_state)
        self.rejected = 0
        self._inputs = None

    def _read_messages(self):
        """Collect the commands (with their ranks in the file) and the recorded states."""
        topics = {rel: t for rel, t in self.topics.items() if t}
        arrays = self.rec.topic_arrays(list(topics.values()))
        if arrays is None:                  # no message index: the message list
            return self._read_message_list(topics)
        for rel, topic in topics.items():
            a = arrays[topic]
            if rel in T.COMMAND_TOPICS:     # ranked among the messages of their log time
                self.events.add_topic(rel, a.log_times, a.ranks, a.data)
            elif rel in T.STATE_TOPICS and len(a.log_times):
                k, r = np.divmod(a.log_times - self.t0, self.dt_ns)
                on_tick = (r == 0) & (k > 0)
                if on_tick.all() and (k[1:] > k[:-1]).all():   # one per tick, in order
                    self.states[rel] = (k, a.data)
                    continue
                ok = np.flatnonzero(on_tick)
                by_tick = np.argsort(k[ok], kind='stable')
                o, k = ok[by_tick], k[ok][by_tick]
                last = np.append(k[1:] != k[:-1], True)     # one state per tick: the last
                keep = o[last]
                data = a.data[keep] if isinstance(a.data, np.ndarray) else [
                    a.data[i] for i in keep]
                self.states[rel] = (k[last], data)

    def _read_message_list(self, topics):
        """Collect commands and states from ``rec.messages`` (a file without message indexes)."""
        if not self.rec.messages:
            self.rec.load(list(topics.values()))
        by_topic = {t: rel for rel, t in topics.items()}
        items, ranks = [], []
        states = {}
        same_t, rank = None, 0
        for log_time, topic, data in self.rec.messages:
            if log_time != same_t:
                same_t, rank = log_time, 0
            rank += 1
            rel = by_topic.get(topic)
            if rel in T.COMMAND_TOPICS:
                items.append((log_time, rel, data))
                ranks.append(rank)
            elif rel in T.STATE_TOPICS:
                k, r = divmod(log_time - self.t0, self.dt_ns)
                if r == 0 and k > 0:
                    states.setdefault(rel, {})[k] = data
        for rel, by_k in states.items():
            ks = sorted(by_k)
            self.states[rel] = (np.array(ks, dtype=np.int64), [by_k[k] for k in ks])
        self.events.add_items(items, ranks)

    def _read_records(self):
        """Collect the parameter updates, resets and fault clearings, with their sort keys."""
        items, keys = [], []
        for name, data in self.rec.metadata:
            if name in MODEL_EVENTS and 'log_time_ns' in data:
                try:
                    log_time = int(data['log_time_ns'])
                    before = int(data.get('messages_at_log_time', -1))
                except ValueError as exc:
                    raise RunError(f'{self.rec.path}: bad "{name}" metadata record: '
                                   f'{exc}') from None
                items.append((log_time, name, data))
                # after the first `before` messages of its log time; else after all
                keys.append(before + 0.5 if before >= 0 else math.inf)
        self.events.add_items(items, keys)

    # ----------------------------------------------------------------- inputs
    def inputs(self):
        """
        Return the drive command of every step, as the node's CommandHold delivered it.

        Returns
        -------
        segments : list of Segment
            The stretches between model events (parameter updates, resets,
            fault clearings), in order; each segment's ``groups`` are the
            event groups of its steps: ``(e0, e1, k, n)``, events ``e0 .. e1 -
            1`` of :attr:`events`, the first acting on step ``k``; ``n`` > 0: a
            run of ``n`` steps with one Float64 drive command each, else the
            events of step ``k``.
        commands : numpy.ndarray, shape (n_steps, 4)
            The drive command rows of ``model.run`` (theta sense); a row with a
            NaN mode takes the command the model holds (the steps of a segment
            before its first new command).
        forces : numpy.ndarray, shape (n_steps,)
            The external force of each step [N].

        Notes
        -----
        The result is computed once; it does not depend on the physics
        parameters the model runs with (only on the recorded fault, delay
        and timeout settings and the axis's lead and initial position).

        """
        if self._inputs is None:
            command_pass = CommandPass(self)
            self._inputs = command_pass.build()
            self.stale = command_pass.stale     # per step: the command timed out
        return self._inputs

    # ------------------------------------------------------------- the model
    def model(self, overrides=None):
        """Return a new model with the recorded parameters and ``overrides`` (names: values)."""
        from ...core.model import LeadScrewModel
        params = ScrewParams.from_dict(overrides, base=self.params) if overrides else self.params
        return LeadScrewModel(params, dt=self.dt_ns / NS, ageing=self.ageing)

    def blocks(self, model, line=None, overrides=None, progress=None, block_ticks=None,
               log=None, values=None):
        """
        Run the segments through ``model``; yield (segment, columns of ``model.run``).

        With ``block_ticks``, a segment runs in parts of at most that many
        steps (each a Segment of its own, its groups cut there): the writer
        then compresses one part while the model runs the next.

        Parameters
        ----------
        model : LeadScrewModel
            A new model (:meth:`model`).
        line : StateDelivery, optional
            Follows the recorded fault updates and resets too.
        overrides : dict, optional
            Physics parameters kept across the recorded updates.
        progress : Progress, optional
            Told the steps done after each segment.
        block_ticks : int, optional
            The longest part [steps] (default: whole segments).
        log : EventLog, optional
            Gets the columns of every part, the recorded parameter updates and
            the steps whose command timed out (:mod:`.run_events`).
        values : iterable of str, optional
            Only these columns (``model.run``'s lean path; default all).

        """
        segments, commands, forces = self.inputs()
        keep = set(self.overrides) | set(overrides or ())
        if log is not None:
            log.stale = self.stale
        for seg in segments:
            for kind, data in seg.events:
                self._apply_model(kind, data, model, line, keep)
            if log is not None:
                log.segment(seg, model.params)
            if seg.k1 <= seg.k0:
                continue
            rows = commands[seg.k0:seg.k1]
            held = np.isnan(rows[:, 0])
            if held.any():
                rows = rows.copy()
                rows[held] = model.held_command()
            for part in _parts(seg, block_ticks):
                a, b = part.k0 - seg.k0, part.k1 - seg.k0
                with simulation_faults(f' in steps {part.k0}..{part.k1 - 1}'):
                    cols = model.run(None, forces[part.k0:part.k1], commands=rows[a:b],
                                     values=values)
                if log is not None:
                    log.add(part.k0, cols)
                yield part, cols
                if progress is not None:
                    progress.update(part.k1)
        if progress is not None:
            progress.done()

    def replay(self, overrides=None, values=None):
        """
        Return the columns of ``model.run`` of every step of the recording.

        Parameters
        ----------
        overrides : dict, optional
            Physics parameters {name: value} on top of the recorded ones, kept
            across the recorded updates.
        values : iterable of str, optional
            Only these columns (``model.run``'s lean path; default all).

        Returns
        -------
        dict of numpy.ndarray
            One entry per step 0 .. n_steps - 1 (the state after step k, logged
            at ``t0 + (k + 1) dt``), the keys of ``LeadScrewModel.run``.

        """
        model = self.model(overrides)
        parts = [cols for _seg, cols in self.blocks(model, overrides=overrides, values=values)]
        if not parts:
            return {}
        return {name: np.concatenate([p[name] for p in parts]) for name in parts[0]}

    def run(self, writer=None, progress=None, log=None):
        """
        Re-simulate every step; optionally write a new recording in the node's layout.

        Parameters
        ----------
        writer : RunWriter, optional
            Gets the recorded commands and the new states, in the node's order.
        progress : Progress, optional
            Told the steps done after each segment.
        log : EventLog, optional
            Collects the run's events (:meth:`blocks`).

        Returns
        -------
        (NewStates, LeadScrewModel)
            The states the node would have published, by step of their log
            time, and the model after the last step.

        """
        model = self.model()
        line = self.line = StateDelivery(model.params)
        enc = M.StateEncoder(self.prefix, self.params.anti_backlash)
        new = NewStates(self.n_steps, len(M.TRUTH_VALUES))
        for seg, cols in self.blocks(model, line, progress=progress, block_ticks=BLOCK_TICKS,
                                     log=log):
            pieces = self._pieces(seg, writer) if writer is not None else []
            if self.decimation == 1 and not (line.delay or line.drop_rate or line.pending()):
                _block_states(self, seg, cols, pieces, enc, writer, new)
            else:
                _tick_states(self, seg, cols, pieces, enc, writer, new, line)
        return new, model

    def _pieces(self, seg, writer):
        """Return the recorded command messages of a segment as tick_writer pieces."""
        events, ids, pieces = self.events, writer.ids, []
        for e0, e1, k, run in seg.groups:
            i = k - seg.k0
            if run:
                rows = events.rows(e0, e1)          # the recorded rows, as read
                if rows is None:
                    datas = [d for _t, _kind, d in events[e0:e1]]
                    if len({len(d) for d in datas}) == 1:
                        rows = np.frombuffer(b''.join(datas), dtype=np.uint8).reshape(run, -1)
                if rows is not None:
                    pieces.append(Stream(i, i + run, ids[events.kind(e0)], rows,
                                         events.times[e0:e1]))
                    continue
                pieces.extend(Events(i + j, [(ids[kind], d, t)])
                              for j, (t, kind, d) in enumerate(events[e0:e1]))
                continue
            messages = [(ids[kind], d, t) for t, kind, d in events[e0:e1] if kind in ids]
            if messages:
                pieces.append(Events(i, messages))
        return pieces

    def _apply_model(self, kind, data, model, line, keep):
        """Apply a model event: a parameter update, a reset or a fault clearing."""
        if kind == UPDATE_RECORD:
            changes = {n: v for n, v in data.items() if n not in keep}
            try:
                params = ScrewParams.from_text(changes, base=model.params)
            except ParameterError as exc:
                raise RunError(f'{self.rec.path}: recorded {exc}') from None
            model.set_params(params)
            if line is not None:
                line.set_faults(params)
        elif kind == RESET_RECORD:
            model.reset()
            if line is not None:
                line.reset()
        elif kind == CLEAR_FAULT_RECORD:
            model.clear_fault()
        elif kind == RELUBRICATE_RECORD:
            model.relubricate()

    def joint_labels(self):
        """Return the two joint names."""
        return (self.prefix + 'screw_joint', self.prefix + 'nut_joint')


def _parts(seg, block_ticks):
    """Return ``seg`` cut into Segments of at most ``block_ticks`` steps (its groups cut too)."""
    if not block_ticks or seg.k1 - seg.k0 <= block_ticks:
        return [seg]
    parts = []
    groups = list(seg.groups)
    for a in range(seg.k0, seg.k1, block_ticks):
        part = Segment(a, seg.events if a == seg.k0 else [])
        part.k1 = min(a + block_ticks, seg.k1)
        rest = []
        for e0, e1, k, run in groups:
            if k >= part.k1:
                rest.append((e0, e1, k, run))
            elif run and k + run > part.k1:         # a run across the cut
                inside = part.k1 - k
                part.groups.append((e0, e0 + inside, k, inside))
                rest.append((e0 + inside, e1, part.k1, run - inside))
            else:
                part.groups.append((e0, e1, k, run))
        groups = rest
        parts.append(part)
    return parts


class NewStates:
    """
    The states a re-simulation publishes, by step of their log time (1 .. n_steps).

    ``sensor[k]``: the joint_states values (:data:`messages.SENSOR_VALUES`) delivered at
    step k's log time (the last one when several arrive), ``has_sensor[k]``
    whether any; ``truth[k]``: the truth values (:data:`messages.TRUTH_VALUES`) of a
    sampled step, ``has_truth[k]``.
    """

    def __init__(self, n_steps, n_truth):
        """Make room for ``n_steps`` steps."""
        self.sensor = np.full((n_steps + 1, len(M.SENSOR_VALUES)), np.nan)
        self.has_sensor = np.zeros(n_steps + 1, dtype=bool)
        self.truth = np.full((n_steps + 1, n_truth), np.nan)
        self.has_truth = np.zeros(n_steps + 1, dtype=bool)


def _block_states(sim, seg, cols, pieces, enc, writer, new):
    """Keep (and write) the states of a segment whose every step publishes at once."""
    k0, k1 = seg.k0, seg.k1
    sensed = {name: cols[col] for name, col in zip(M.SENSOR_VALUES, M.SENSOR_COLUMNS)}
    new.sensor[k0 + 1:k1 + 1] = np.column_stack([sensed[n] for n in M.SENSOR_VALUES])
    new.has_sensor[k0 + 1:k1 + 1] = True
    new.truth[k0 + 1:k1 + 1] = np.column_stack([cols[n] for n in M.TRUTH_VALUES])
    new.has_truth[k0 + 1:k1 + 1] = True
    if writer is None:
        return
    t_state = sim.t0 + (np.arange(k0, k1, dtype=np.int64) + 1) * sim.dt_ns
    stamps = Stamps(t_state)                  # one stamp per tick, on each message
    analysis = {name: np.asarray(cols[col], dtype=float)
                for name, col in zip(M.ANALYSIS_VALUES, M.ANALYSIS_COLUMNS)}
    states = (enc.encoded('sensor', stamps, sensed) + enc.encoded('truth', stamps, cols)
              + enc.encoded('analysis', stamps, analysis))
    rows = [r for _topic, r in states]
    chans = [writer.ids[topic] for topic, _r in states]
    if writer.tf is not None:
        rows.append(writer.tf_rows(stamps, sensed['screw_angle'], sensed['nut_position']))
        chans.append(writer.ids['/tf'])
    write_block(writer.rec, pieces, chans, rows, t_state)


def _tick_events(pieces):
    """Return {block index: [(channel, bytes, log time)]} of tick_writer pieces."""
    out = {}
    for p in pieces:
        if isinstance(p, Events):
            out.setdefault(p.i0, []).extend(p.messages)
        else:
            for j in range(p.i1 - p.i0):
                out.setdefault(p.i0 + j, []).append(
                    (p.channel, p.rows[j].tobytes(), int(p.log_times[j])))
    return out


def _tick_states(sim, seg, cols, pieces, enc, writer, new, line):
    """Keep (and write) the states of a segment step by step, through the state delivery."""
    events = _tick_events(pieces)
    dec, dt_ns = sim.decimation, sim.dt_ns
    sensor = np.column_stack([cols[c] for c in M.SENSOR_COLUMNS]).tolist()
    truth = np.column_stack([cols[n] for n in M.TRUTH_VALUES]).tolist()
    analysis = np.column_stack([cols[c] for c in M.ANALYSIS_COLUMNS]).tolist()
    for i, k in enumerate(range(seg.k0, seg.k1)):
        now = sim.t0 + (k + 1) * dt_ns
        if writer is not None:
            for channel, data, log_time in events.get(i, ()):
                writer.write(channel, data, log_time)
        sampled = (k + 1) % dec == 0
        if sampled:
            line.sample(k + 1, now, tuple(sensor[i]))
        values = None
        for stamp, values in line.due(k + 1):
            new.sensor[k + 1] = values
            new.has_sensor[k + 1] = True
            if writer is not None:
                for topic, data in enc.sensor(stamp, values):
                    writer.write(writer.ids[topic], data, now)
        if sampled:
            new.truth[k + 1] = truth[i]
            new.has_truth[k + 1] = True
            if writer is not None:
                for topic, data in enc.truth(now, truth[i]) + enc.analysis(now, analysis[i]):
                    writer.write(writer.ids[topic], data, now)
        if values is not None and writer is not None:
            writer.write_tf(stamp, values[0], values[1], now)
