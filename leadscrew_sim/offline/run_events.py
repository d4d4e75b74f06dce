"""
The events of an offline run (``simulate``, ``resim``, ``info``): the arrays they come from.

:class:`EventLog` collects, block by block, the columns of ``model.run``
(nut position, limit and home switches, drive fault code), the command's
staleness and the parameter changes of a run, and hands them to
:func:`leadscrew_sim.analysis.events.run_events`. :func:`recorded_events`
reads the same from a recording's own messages: the nut position of
``sim/joint_states`` (else ``joint_states``), the switch topics and the
recorded parameter updates.
"""
import numpy as np

from .options import NS
from ..analysis.events import FAULT_FIELDS, run_events
from ..core.params import ParameterError, ScrewParams
from ..io import cdr as C
from ..io.run_file import UPDATE_RECORD

#: The switch columns of ``model.run``, with their switch topics.
SWITCH_COLUMNS = (('limit_min', 'limit_switch/min'), ('limit_max', 'limit_switch/max'),
                  ('home', 'home_switch'))


class EventLog:
    """
    The per-tick arrays of a run, collected block by block, and its parameter changes.

    Parameters
    ----------
    params : ScrewParams
        The parameters at the start of the run (stroke, injected faults).
    dt_ns : int
        The step [ns]; the columns of step k are the state at (k + 1) dt.

    """

    def __init__(self, params, dt_ns):
        """Start with no tick."""
        self.params, self.dt_ns = params, dt_ns
        self.initial = {n: getattr(params, n) for n in FAULT_FIELDS}
        self._faults = dict(self.initial)       # the injected faults noted last
        self._x, self._fault, self._k0 = [], [], []
        self._switch = {name: [] for name, _topic in SWITCH_COLUMNS}
        self.stale = None
        self.changes = []           # (time [s], {field name: value})

    def add(self, k0, cols):
        """Add the columns of ``model.run`` for the steps from ``k0`` on."""
        x = np.asarray(cols['nut_position'], dtype=float)
        self._k0.append(k0)
        self._x.append(x)
        self._fault.append(np.asarray(cols['fault'], dtype=np.int8) if 'fault' in cols
                           else np.zeros(len(x), dtype=np.int8))
        for name, _topic in SWITCH_COLUMNS:
            self._switch[name].append(np.asarray(cols[name], dtype=bool) if name in cols
                                      else np.zeros(len(x), dtype=bool))

    def change(self, k, values):
        """Note parameter changes ``{field name: value}`` that act from step ``k``."""
        self.changes.append((k * self.dt_ns / NS, dict(values)))
        self._faults.update((n, v) for n, v in values.items() if n in self._faults)

    def change_text(self, k, record, params):
        """
        Note a recorded parameter update (names and values as text) acting from step ``k``.

        Returns the parameters after it (``params`` when it does not parse).
        """
        try:
            new = ScrewParams.from_text(record, base=params)
        except (ParameterError, ValueError, TypeError):
            return params
        changed = {n: getattr(new, n) for n in FAULT_FIELDS
                   if getattr(new, n) != getattr(params, n)}
        if changed:
            self.change(k, changed)
        return new

    def segment(self, seg, params):
        """
        Note the injected faults a Resim segment's model events set: ``params`` after them.

        A segment after parameter updates starts at step ``seg.k0``.
        """
        changed = {n: getattr(params, n) for n in FAULT_FIELDS
                   if getattr(params, n) != self._faults.get(n, self.initial[n])}
        if changed:
            self.change(seg.k0, changed)
            self._faults.update(changed)

    def events(self):
        """Return the events of the ticks and changes so far (analysis.events.run_events)."""
        if not self._x:
            return run_events([], [], self._stroke(), changes=self.changes,
                              initial_faults=self.initial)
        x = np.concatenate(self._x)
        k = np.concatenate([k0 + np.arange(len(a)) for k0, a in zip(self._k0, self._x)])
        stale = None
        if self.stale is not None:
            stale = np.asarray(self.stale, dtype=bool)[k]
        return run_events((k + 1) * self.dt_ns / NS, x, self._stroke(),
                          {n: np.concatenate(a) for n, a in self._switch.items()},
                          np.concatenate(self._fault), stale, self.changes, self.initial)

    def _stroke(self):
        return self.params.stroke_min, self.params.stroke_max


def recorded_events(rec, meta, params):
    """
    Return the events read from a recording's own messages and parameter updates.

    The nut position of ``sim/joint_states`` (else ``joint_states``: the
    sensor), the switch topics (std_msgs/Bool) and the parameter update
    records; times from the recording's ``t0_ns`` (else its first message).
    """
    from ..analysis.events import Event
    t0 = int(meta.get('t0_ns', 0)) if meta is not None else None
    truth, sensor = rec.role_topic('sim/joint_states'), rec.role_topic('joint_states')
    topics = {t: name for name, t0pic in SWITCH_COLUMNS
              for t in [rec.role_topic(t0pic)] if t}
    xs = {truth: ([], []), sensor: ([], [])}
    flips = []
    if not rec.messages:
        rec.load([t for t in [truth, sensor] + list(topics) if t])
    for log_time, topic, data in rec.messages:
        if t0 is None:
            t0 = log_time
        if topic in xs and topic:
            _s, names, pos, _v, _e = C.decode_joint_state(data)
            i = next((j for j, n in enumerate(names) if n.endswith('nut_joint')), None)
            if i is not None and i < len(pos):
                xs[topic][0].append(log_time)
                xs[topic][1].append(pos[i])
        elif topic in topics:
            flips.append((log_time, topics[topic], bool(data[4])))
    t0 = t0 or 0
    times, x = xs[truth] if truth and xs[truth][0] else xs.get(sensor, ([], []))
    time = (np.asarray(times, dtype=np.int64) - t0) / NS
    switch_events = []
    state = {}
    for log_time, name, on in flips:
        if state.get(name, False) != on:
            switch_events.append((log_time, name, on))
        state[name] = on
    log = EventLog(params, 1)           # steps of 1 ns: a step is a log time from t0
    for name, data in rec.metadata:
        if name == UPDATE_RECORD and 'log_time_ns' in data:
            record = {n: v for n, v in data.items()
                      if n not in ('log_time_ns', 'messages_at_log_time')}
            params = log.change_text(int(data['log_time_ns']) - t0, record, params)
    events = run_events(time, x, (log.params.stroke_min, log.params.stroke_max),
                        changes=log.changes, initial_faults=log.initial)
    from ..analysis.events import SWITCHES
    for log_time, name, on in switch_events:
        events.append(Event((log_time - t0) / NS, f'{name}_{"on" if on else "off"}',
                            SWITCHES[name][0 if on else 1]))
    return sorted(events, key=lambda e: e.time)
