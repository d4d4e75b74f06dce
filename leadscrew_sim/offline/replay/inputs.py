"""
The pass of a recording's events through the node's CommandHold: the drive command of each step.

:meth:`leadscrew_sim.offline.replay.resim.Resim.inputs` runs it once. Runs of one
std_msgs/Float64 drive command per step with no timeout, delay or loss are
taken in one vectorised go, with the same doubles CommandHold forms; all
else goes event by event, step by step, through CommandHold itself.
"""
import numpy as np

from ..options import NS, RunError
from ...core.commands import CommandHold, DROPPED, JOINT_COMMAND_MODES, NutMap, REJECTED
from ...core.params import ParameterError, ScrewParams
from ...io import cdr as C
from ...io.run_file import (CLEAR_FAULT_RECORD, RELUBRICATE_RECORD, RESET_RECORD, run_setting,
                            UPDATE_RECORD)

#: The recorded events that act on the model itself; a stretch of one compiled call ends there.
MODEL_EVENTS = (UPDATE_RECORD, RESET_RECORD, CLEAR_FAULT_RECORD, RELUBRICATE_RECORD)

#: The std_msgs/Float64 drive commands, by their CommandHold method.
FLOAT_COMMANDS = ('torque_command', 'velocity_command', 'position_command')


class Segment:
    """
    Steps ``k0 .. k1 - 1`` of a recording, run in one compiled call.

    ``events``: the model events ``[(kind, data)]`` applied before step ``k0``;
    ``groups``: the event groups of its steps (see :meth:`Resim.inputs`).
    """

    __slots__ = ('k0', 'k1', 'events', 'groups')

    def __init__(self, k0, events):
        """Start at step ``k0`` after ``events``."""
        self.k0, self.k1, self.events, self.groups = k0, k0, events, []


class CommandPass:
    """The pass of the recorded events of a Resim through the node's CommandHold."""

    def __init__(self, sim):
        """Start with the recorded parameters and run settings of ``sim``."""
        from ...core.model import LeadScrewModel
        self.sim = sim
        self.model = LeadScrewModel(sim.params, dt=sim.dt_ns / NS)   # stepped never
        timeout = sim.timeout if sim.clock_mode != 'realtime' else 0.0
        self.hold = CommandHold(sim.prefix, timeout, NutMap.of_model(self.model),
                                sim.joint_command_mode, self.model.params)
        n = sim.n_steps
        self.commands = np.full((n, 4), np.nan)
        self.forces = np.zeros(n)
        self.stale = np.zeros(n, dtype=bool)    # the command timed out at the step
        self.current = None         # the command of the last step, None: the model's own
        self.k = 0                  # the next step to fill

    def build(self):
        """Return (segments, commands, forces) as :meth:`Resim.inputs` describes them."""
        sim = self.sim
        events, n = sim.events, sim.n_steps
        times = events.times
        ticks = np.maximum(0, -((sim.t0 - times) // sim.dt_ns))     # core.commands.first_step
        segments = [Segment(0, [])]
        sim.rejected = 0
        for e0, e1, k, run in _groups(events, ticks, n):
            self._fill(k)
            if run and self._quiet():
                self._float_run(events, e0, e1, k)
                segments[-1].groups.append((e0, e1, k, run))
                continue
            if run:                 # timeouts, delay or loss: step by step
                for i in range(run):
                    self._fill(k + i)
                    self._apply(events[e0 + i][1], events[e0 + i][2],
                                sim.t0 + (k + i) * sim.dt_ns)
                    self._step(k + i)
                    segments[-1].groups.append((e0 + i, e0 + i + 1, k + i, 0))
                continue
            model_events = [(kind, data) for _t, kind, data in events[e0:e1]
                            if kind in MODEL_EVENTS]
            if model_events:
                segments[-1].k1 = k
                segments.append(Segment(k, model_events))
                self.current = None
            t_k = sim.t0 + k * sim.dt_ns
            for _t, kind, data in events[e0:e1]:
                self._apply(kind, data, t_k)
            self._step(k)
            segments[-1].groups.append((e0, e1, k, 0))
        self._fill(n)
        segments[-1].k1 = n
        return segments, self.commands, self.forces

    def _quiet(self):
        """Return True when only commands change the drive command (no timeout, delay, loss)."""
        h = self.hold
        return h.timeout <= 0.0 and h.delay <= 0 and h.drop_rate <= 0.0

    def _fill(self, k_end):
        """Fill the steps up to ``k_end`` that have no events."""
        if self._quiet():
            k = self.k
            if k_end > k:
                if self.current is not None:
                    self.commands[k:k_end] = self.current
                self.forces[k:k_end] = self.hold.force
                self.k = k_end
            return
        for k in range(self.k, k_end):
            self._step(k)

    def _step(self, k):
        """Take the drive command of step ``k`` from the hold."""
        command = self.hold.changed_command(self.sim.t0 + k * self.sim.dt_ns)
        if command is not None:
            self.current = command
        if self.current is not None:
            self.commands[k] = self.current
        self.forces[k] = self.hold.force
        self.stale[k] = self.hold.stale
        self.k = k + 1

    def _float_run(self, events, e0, e1, k):
        """Take a run of one Float64 drive command per step in one go (CommandHold.take_series)."""
        kind = events.kind(e0)
        recorded = events.rows(e0, e1)
        values = C.decode_float64s(recorded if recorded is not None else
                                   [data for _t, _kind, data in events[e0:e1]])
        n = e1 - e0
        dt_ns, t0 = self.sim.dt_ns, self.sim.t0
        times = t0 + (k + np.arange(n, dtype=np.int64)) * dt_ns
        rows = self.hold.take_series(kind, values, times)
        if rows is None:                # the hold rejects some: step by step
            for i, (_t, kind, data) in enumerate(events[e0:e1]):
                self._apply(kind, data, int(times[i]))
                self._step(k + i)
            return
        self.commands[k:k + n] = rows
        self.current = self.hold.changed_command(int(times[-1]))
        self.forces[k:k + n] = self.hold.force
        self.k = k + n

    def _apply(self, kind, data, t_k):
        """Apply one event to the hold at step time ``t_k`` [ns]; count the rejected commands."""
        sim, hold = self.sim, self.hold
        if kind in FLOAT_COMMANDS:
            reason = getattr(hold, kind)(C.decode_float64(data), t_k)
            sim.rejected += reason not in (None, DROPPED)
        elif kind == 'joint_commands':
            _s, names, pos, vel, eff = C.decode_joint_state(data)
            sim.rejected += hold.joint_commands(names, pos, vel, eff, t_k)[0] == REJECTED
        elif kind == 'external_force':
            sim.rejected += hold.external_force(C.decode_float64(data)) is not None
        elif kind == UPDATE_RECORD:
            changes = {n: v for n, v in data.items() if n not in sim.overrides}
            try:
                params = ScrewParams.from_text(changes, base=self.model.params)
            except ParameterError as exc:
                raise RunError(f'{sim.rec.path}: recorded {exc}') from None
            self.model.set_params(params)
            hold.set_faults(params)
            if 'command_timeout' in data and sim.clock_mode != 'realtime':
                hold.timeout = run_setting(data, 'command_timeout', hold.timeout)
            if 'joint_command_mode' in data:
                hold.joint_mode = JOINT_COMMAND_MODES[run_setting(data, 'joint_command_mode',
                                                                  'auto')]
        elif kind == RESET_RECORD:
            self.model.reset()
            hold.reset()
            hold.nut_map = NutMap.of_model(self.model)


def _groups(events, ticks, n):
    """
    Return the event groups (e0, e1, k, run) of the steps before ``n``.

    ``run`` > 0: events ``e0 .. e1 - 1`` are one Float64 drive command of one
    kind per step, on the consecutive steps ``k .. k + run - 1``; ``run`` = 0:
    the events of step ``k`` alone. ``ticks``: the step of each event
    (non-decreasing).
    """
    ne = int(np.searchsorted(ticks, n, side='left'))
    ticks = np.asarray(ticks[:ne], dtype=np.int64)
    if not ne:
        return []
    kinds = events.codes({kind: i for i, kind in enumerate(FLOAT_COMMANDS)}, ne)
    same = ticks[1:] == ticks[:-1]
    alone = np.ones(ne, dtype=bool)             # the only event of its step
    alone[1:] &= ~same
    alone[:-1] &= ~same
    simple = alone & (kinds >= 0)
    linked = (simple[1:] & simple[:-1] & (kinds[1:] == kinds[:-1])
              & (ticks[1:] == ticks[:-1] + 1))
    bounds = np.concatenate([[0], np.flatnonzero(~linked) + 1, [ne]]).tolist()
    ticks_list = ticks.tolist()
    groups = []
    for e, f in zip(bounds[:-1], bounds[1:]):
        if f - e > 1:                           # a run of linked simple commands
            groups.append((e, f, ticks_list[e], f - e))
        elif groups and groups[-1][3] == 0 and groups[-1][2] == ticks_list[e]:
            g = groups[-1]                      # another event of the same step
            groups[-1] = (g[0], f, g[2], 0)
        else:
            groups.append((e, f, ticks_list[e], 0))
    return groups
