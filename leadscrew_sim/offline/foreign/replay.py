"""
Re-simulating a foreign recording: its mapped commands through the model, on a grid of steps.

The grid starts at the first command's time plus the command-to-state delay
and steps at ``step_rate`` (default 1 kHz, or the command rate where
faster). The commands go through the node's rules
(:class:`~leadscrew_sim.core.commands.CommandHold`) and act from their time on
the grid (:mod:`.commands`). The state after step k lies at
``t0 + (k + 1) dt``; a recorded state at stamp s is compared with the
re-simulation *at s*: between the two steps around s, positions by cubic
Hermite interpolation with the re-simulated velocities as slopes (error of
order dt^4 times the fourth derivative, far below any encoder's noise at
1 kHz), other signals linearly. Taking the nearest step instead would err
by up to half a step times the velocity (10 mrad at 20 rad/s and 1 kHz),
more than a fine encoder's noise.
"""
import copy
import dataclasses

import numpy as np

from . import delay as D
from .commands import Commands, CommandSet
from .forces import find_forces, held_forces
from .mapping import COMMAND_TYPES, DEFAULT_STEP_RATE, JOINT_STATE, KIND_ALIASES, Mapping
from .segments import motion_segments
from .states import COLUMNS, States
from ..options import NS, RunError
from ...core.commands import CommandHold, NutMap
from ...core.params import ParameterError, ScrewParams
from ...io.topics import graph_name

#: Slope column of each position column (model.run names).
SLOPES = {'sensor_screw_angle': 'motor_velocity', 'sensor_nut_position': 'nut_velocity',
          'motor_angle': 'motor_velocity', 'nut_position': 'nut_velocity'}

#: Signals compared with an offset removed (an encoder's zero is arbitrary).
OFFSET_SIGNALS = ('screw_angle',)


#: Travel of the states [m, rad] beyond which a recording moves (commands that cannot move
#: the axis are then the wrong topic).
STILL_NUT, STILL_SCREW = 1e-4, 0.1

#: The node's own command topics and their kinds (None: a JointState, the node's mode rule).
OWN_COMMANDS = (('torque_command', 'torque'), ('velocity_command', 'velocity'),
                ('position_command', 'position'), (graph_name('joint_commands'), None))


def own_command_specs(rec):
    """
    Return the mapping specs of the node's own command topics that carry messages.

    A ``ros2 bag record`` of the node holds its topics under their names, but
    not its parameters record: its commands are those of its command topics,
    of the kinds their names say, the latest in force.
    """
    found = []
    for name, kind in OWN_COMMANDS:
        for topic, ty in rec.topic_types.items():
            if (topic == '/' + name or topic.endswith('/' + name)) and ty in COMMAND_TYPES:
                found.append(topic)
    if not found:
        return []
    arrays = rec.topic_arrays(found)
    kinds = dict(OWN_COMMANDS)
    out = []
    for topic in found:
        if len(arrays[topic].log_times):
            name = next(n for n, _k in OWN_COMMANDS if topic.endswith(n))
            out.append((topic, kinds[name], None, None))
    return out


def find_topic(rec, name, option):
    """
    Return the recorded topic ``name`` (relative names match any namespace; ours first).

    ``option``: the keyword of the option that names it, for the error.
    """
    ours = graph_name(name.lstrip('/'))
    for topic in rec.topic_types:       # the node's own name (axis/joint_states) first
        if ours != name.lstrip('/') and (topic == '/' + ours or topic.endswith('/' + ours)):
            return topic
    for topic in rec.topic_types:
        if topic == name or topic == '/' + name.lstrip('/') or topic.endswith('/' + name):
            return topic
    raise RunError(f"<<{option}>> {name}: no such topic in {rec.path} (topics: "
                   f"{', '.join(sorted(rec.topic_types))})")


class ForeignReplay:
    """
    A foreign recording mapped onto the model: its states, its commands, the grid and the delay.

    Parameters
    ----------
    mapping : Mapping or argparse.Namespace
        The mapping (options are turned into one by :meth:`Mapping.from_args`).
    rec : Recording
        The recording (its messages need not be loaded).
    params : ScrewParams
        The axis's parameters (initial_position is set from the measured nut
        position at the start, :meth:`_start_position`).
    estimate_delay : bool
        Estimate the delay with ``params`` when the mapping does not set it
        (one re-simulation; :mod:`.delay`). Else it is 0 unless set: an
        estimate with parameters far from the axis's is biased (the twin's
        lag then differs), so ``identify`` fits at the delay it is given.

    Attributes
    ----------
    states : States
    commands : Commands
    forces : Forces or None
        The node's external force input, where recorded (:mod:`.forces`).
    t0 : int
        Grid start [ns] (first command time + delay).
    dt_ns : int
        Step [ns].
    n_steps : int
    delay : Delay

    """

    def __init__(self, mapping, rec, params, estimate_delay=False):
        """Find the topics and joints, read the states and commands, set the grid."""
        m = mapping if isinstance(mapping, Mapping) else Mapping.from_args(mapping)
        self.mapping, self.path, self.rec = m, rec.path, rec
        self.state_topic = find_topic(rec, m.state_topic or 'joint_states', 'state_topic')
        stype = rec.topic_types.get(self.state_topic)
        if stype != JOINT_STATE:
            raise RunError(f'<<state_topic>> {self.state_topic}: type {stype!r}, expected '
                           f'{JOINT_STATE}')
        specs = m.specs() if m.command_topic is not None else own_command_specs(rec)
        if not specs:
            raise RunError('<<command_topic>>: a foreign recording needs the command topic '
                           f'(`leadscrew_sim info {rec.path}` lists the topics and the '
                           'mapping flags that fit)')
        topics = [find_topic(rec, t, 'command_topic') for t, _k, _i, _j in specs]
        self.command_topic = ', '.join(topics)
        arrays = rec.topic_arrays([self.state_topic] + topics)
        self.joints = (m.screw_joint or 'screw_joint', m.nut_joint or 'nut_joint')
        names = _state_names(arrays[self.state_topic])
        screw = self.joints[0] if (m.screw_joint or self.joints[0] in names) else None
        nut = self.joints[1] if (m.nut_joint or self.joints[1] in names) else None
        if screw is None and nut is None:
            raise RunError(f'<<screw_joint>>/<<nut_joint>>: the states on {self.state_topic} name '
                           f'{", ".join(names) or "no joint"}; give the screw or the nut joint')
        self.states = States(self.state_topic, arrays[self.state_topic], screw, nut, rec.path)
        self.commands = CommandSet(
            Commands(t, rec.topic_types.get(t), arrays[t],
                     dataclasses.replace(m, command_topic=t, command_kind=kind,
                                         command_index=index, command_joint=joint),
                     self.joints, rec.path)
            for t, (_t, kind, index, joint) in zip(topics, specs))
        self.forces = find_forces(rec, self.state_topic, topics)    # the node's load input
        self._check_moves()
        first, last = self.commands.span()
        s0, s1 = int(self.states.stamps[0]), int(self.states.stamps[-1])
        if s1 < first or s0 > last + 10 * NS:
            raise RunError(f'{rec.path}: no overlap between the commands on '
                           f'{self.command_topic} ({first / NS:.3f} .. {last / NS:.3f} s) and '
                           f'the states on {self.state_topic} ({s0 / NS:.3f} .. {s1 / NS:.3f} s)')
        rate = m.step_rate or max(DEFAULT_STEP_RATE, round(self.commands.rate()))
        self.dt_ns = int(round(NS / rate))
        self.first = first
        self.x0 = self._start_position()
        self._rows = {}             # the command rows by what they depend on (inputs())
        self._use(params)
        if m.command_delay is None and estimate_delay:
            self.set_delay(self.estimate_delay())

    def _check_moves(self):
        """
        Refuse command topics none of which can move the axis while the states move.

        Torque and velocity commands that are all exactly 0 hold the axis
        still; a twin driven by them cannot explain a recording that moves
        (more than :data:`STILL_NUT` [m] or :data:`STILL_SCREW` [rad]): the
        topic is the wrong one. One line names it, its command count and how
        far the states move.
        """
        idle = []
        for part in self.commands.parts:
            kind = KIND_ALIASES.get(part.command_kind, part.command_kind)
            values = getattr(part, 'values', None)
            if part.kind != 'scalar' or kind not in ('torque', 'velocity') or values is None:
                return
            if np.any(np.asarray(values) != 0.0):
                return
            idle.append(f'{part.topic} ({len(values)} {kind} commands, all 0)')
        moved = []
        for name, still, unit in (('nut_position', STILL_NUT, 'm'),
                                  ('screw_angle', STILL_SCREW, 'rad')):
            y = self.states.values.get(name)
            if y is not None and np.isfinite(y).any():
                span = float(np.nanmax(y) - np.nanmin(y))
                if span > still:
                    moved.append(f'{name} over {span:.3g} {unit}')
        if idle and moved:
            raise RunError(f'<<command_topic>>: {", ".join(idle)} does not move the axis, but '
                           f'the states on {self.state_topic} move ({", ".join(moved)}): map '
                           'the topic that commands it (`leadscrew_sim info` lists them)')

    def _start_position(self):
        """
        Return the nut position the recording starts at [m] (None without nut positions).

        The median of the measured nut positions before the first motion: the
        noise of one reading would otherwise shift the twin's start. A recording
        that moves from its first state on started from rest at the first
        command: the first state less half its velocity times the time since.
        """
        x = self.states.values.get('nut_position')
        if x is None or not np.isfinite(x).any():
            return None
        time = (self.states.stamps - self.states.stamps[0]) / NS
        segments = motion_segments(time, {'nut_position': x}, np.isfinite(x))
        first = segments[0][0] if segments else 0
        before = x[:first][np.isfinite(x[:first])]
        if len(before):
            return float(np.median(before))
        # Moving from the first state on: that state lies after the first command, and the
        # axis was at rest until then. Its motion since, under a constant acceleration from
        # rest, is half its velocity times the time since the first command.
        i = int(np.flatnonzero(np.isfinite(x))[0])
        v = self.states.values.get('nut_velocity')
        since = (int(self.states.stamps[i]) - self.first) / NS
        if v is None or not np.isfinite(v[i]) or not since > 0.0:
            return float(x[i])
        return float(x[i] - 0.5 * v[i] * since)

    # ------------------------------------------------------------------ grid
    def set_delay(self, delay):
        """Use the command-to-state ``delay`` (a Delay): the grid moves with it."""
        self.delay = delay
        self.t0 = self.first + int(round(delay.value * NS))
        last = int(self.states.stamps[-1])
        self.n_steps = max(0, (last - self.t0) // self.dt_ns + 1)
        rel = self.states.stamps - self.t0
        k = rel // self.dt_ns - 1                 # the step whose state lies at or before
        ok = (k >= 0) & (k < self.n_steps - 1)
        later = np.append(k[1:] != k[:-1], True)    # one state per step: the later one
        self.use = np.flatnonzero(ok & later)
        self.k = k[self.use]
        self.frac = (rel[self.use] - (self.k + 1) * self.dt_ns) / self.dt_ns
        self.merged = int(np.count_nonzero(ok & ~later))
        self._inputs = None

    def estimate_delay(self, overrides=None):
        """
        Return the Delay estimated with the parameters (one re-simulation at delay 0).

        ``overrides``: parameter values [their units] that replace this replay's
        (``identify`` estimates again at its fit).
        """
        saved = self.delay
        self.set_delay(D.Delay(0.0, 0.0, 'trial'))
        cols = self.replay(overrides or {}, interpolate=False)
        name = 'nut_position' if 'nut_position' in self.states.values else 'screw_angle'
        if name not in self.states.values:
            self.set_delay(saved)
            return D.Delay(0.0, float('nan'), 'not determined')
        column = COLUMNS[name]
        y = self.states.values[name]
        ok = np.isfinite(y)
        rel = self.states.stamps[ok] - self.t0

        def sim_at(t):
            return at_times(cols, column, self.dt_ns, t, slope=True)
        est = D.estimate(rel, y[ok], sim_at, name, offset=name in OFFSET_SIGNALS,
                         dt=self.dt_ns / NS)
        self.set_delay(saved)
        return est

    # ---------------------------------------------------------------- inputs
    def inputs(self):
        """
        Return (segments [], command rows (n, 4), forces (n,)) as ``Resim.inputs``.

        The rows depend on the parameters only through what the command hold
        reads (the nut-to-motor map, the command delay and loss, the drive
        type): replays of one recording that share those share the rows
        (:meth:`with_params`).
        """
        if self._inputs is None:
            from ...core.model import LeadScrewModel
            model = LeadScrewModel(self.params, dt=self.dt_ns / NS)
            nut_map, params = NutMap.of_model(model), self.params
            key = (nut_map.theta0, nut_map.x0, nut_map.k, int(params.command_delay),
                   float(params.fault_command_drop_rate), params.drive_type,
                   int(params.sensor_seed) if params.fault_command_drop_rate > 0.0 else None,
                   self.t0, self.dt_ns, self.n_steps, self.delay.value)
            if key in self._rows:
                self._inputs = self._rows[key]
                return self._inputs
            hold = CommandHold('', 0.0, nut_map, params=self.params)
            start = None
            traj = next((p for p in self.commands.parts if p.kind == 'trajectory'), None)
            if traj is not None:
                name = 'nut_position' if traj.role == 'nut' else 'screw_angle'
                v = self.states.values.get(name)
                start = float(v[np.isfinite(v)][0]) if v is not None and \
                    np.isfinite(v).any() else None
            rows = self.commands.rows(self.t0, self.dt_ns, self.n_steps, hold,
                                      int(round(self.delay.value * NS)), start)
            rows.flags.writeable = False        # shared by the replays of the key
            forces = held_forces(self.forces, self.t0, self.dt_ns, self.n_steps,
                                 int(round(self.delay.value * NS)))
            forces.flags.writeable = False
            self._inputs = self._rows[key] = ([], rows, forces)
        return self._inputs

    def with_params(self, params):
        """
        Return this replay with other parameters, as a new one would be, without reading again.

        The states and commands are shared; the delay is the mapping's, else
        0 (a new replay does not estimate it).
        """
        new = copy.copy(self)
        new._use(params)
        return new

    def _use(self, params):
        """Take ``params`` at the recording's start position, and the mapping's delay (else 0)."""
        try:
            self.params = ScrewParams.from_dict({'initial_position': self.x0}, base=params) \
                if self.x0 is not None else params
        except ParameterError as exc:
            raise RunError(f'{self.path}: the first measured nut position: {exc}') from None
        m = self.mapping
        self.set_delay(D.Delay(m.command_delay, 0.0, 'set') if m.command_delay is not None
                       else D.Delay(0.0, float('nan'), 'not determined'))

    def model(self, overrides=None):
        """Return a new model with the parameters and ``overrides``."""
        from ...core.model import LeadScrewModel
        params = ScrewParams.from_dict(self._fixed(overrides), base=self.params)
        return LeadScrewModel(params, dt=self.dt_ns / NS)

    def _fixed(self, overrides):
        """Return ``overrides`` with the initial position the recording starts at."""
        out = dict(overrides or {})
        if self.x0 is not None:
            out['initial_position'] = self.x0
        return out

    def replay(self, overrides, n=None, interpolate=True, values=None):
        """
        Return the columns of ``model.run`` of the first ``n`` steps (all: None).

        With ``interpolate``, at each step that has a recorded state the
        sensor columns hold the re-simulation at that state's stamp
        (see the module), so that they compare with :meth:`measured`.
        ``values``: only these columns (``model.run``'s lean path; None: all).
        """
        _seg, rows, forces = self.inputs()
        try:
            cols = self.model(overrides).run(None, forces[:n], commands=rows[:n], values=values)
        except ParameterError as exc:
            raise RunError(f're-simulation with {overrides}: {exc}') from None
        if not interpolate:
            return cols
        return self.at_states(cols)

    def at_states(self, cols, shift_ns=0, only=None):
        """
        Return ``cols`` (of :meth:`replay` without ``interpolate``) at the recorded states.

        The sensor columns at each step that has a recorded state hold the
        re-simulation at that state's stamp less ``shift_ns`` [ns]: a further
        command-to-state delay (the model is time-invariant, so delaying the
        commands delays the states alike); outside the run, its first or last
        step. ``only``: the sensor columns to compute (None: all six).
        """
        cols = dict(cols)
        n_run = len(next(iter(cols.values())))
        k, frac = self.k, self.frac
        if shift_ns:
            rel = (k + 1) * self.dt_ns + np.round(frac * self.dt_ns) - int(shift_ns)
            k = np.clip(rel // self.dt_ns - 1, 0, max(0, n_run - 2)).astype(np.int64)
            frac = np.clip((rel - (k + 1) * self.dt_ns) / self.dt_ns, 0.0, 1.0)
        use = self.k < n_run - 1
        for column in ('sensor_screw_angle', 'sensor_nut_position', 'motor_torque',
                       'sensor_screw_velocity', 'sensor_nut_velocity', 'axial_force'):
            if column not in cols or n_run < 2 or (only is not None and column not in only):
                continue
            c = np.array(cols[column], dtype=float)
            c[self.k[use]] = between(cols, column, k[use], frac[use], self.dt_ns)
            cols[column] = c
        return cols

    def shifted_steps(self, shifts_ns, steps, n_run, every=1):
        """
        Return (k, frac) of the recorded states of ``steps`` for each shift: (shifts, states).

        As :meth:`at_states` places them, for many shifts [ns] at once (the
        alignment's search); ``steps``: the states' steps (``self.k`` inside the
        run of ``n_run`` steps), every ``every``-th of them; :func:`hermite`
        interpolates a column there.
        """
        use = np.flatnonzero(self.k < n_run - 1)[::every]
        base = (self.k[use] + 1) * self.dt_ns + np.round(self.frac[use] * self.dt_ns)
        rel = base[None, :] - np.round(np.asarray(shifts_ns, dtype=float))[:, None]
        k = np.clip(rel // self.dt_ns - 1, 0, max(0, n_run - 2)).astype(np.int64)
        frac = np.clip((rel - (k + 1) * self.dt_ns) / self.dt_ns, 0.0, 1.0)
        return k, frac

    def sample_times(self):
        """Return per step the time of its recorded state [steps from t0] (NaN: none)."""
        a = np.full(self.n_steps, np.nan)
        a[self.k] = self.k + 1 + self.frac
        return a

    def measured(self):
        """Return the measured screw angle, nut position and motor torque per step (NaN: none)."""
        out = {}
        for name in ('screw_angle', 'nut_position', 'motor_torque'):
            a = np.full(self.n_steps, np.nan)
            v = self.states.values.get(name)
            if v is not None:
                a[self.k] = v[self.use]
            out[name] = a
        return out


def _state_names(arrays):
    """Return the joint names of the first state message (none without messages)."""
    from ...io import cdr as C
    if not len(arrays.log_times):
        return []
    try:
        return C.decode_joint_state(bytes(arrays.messages()[0]))[1]
    except C.DecodeError:
        return []


def between(cols, column, k, frac, dt_ns):
    """
    Return ``column`` between the states after steps k and k + 1, at ``frac`` of the step.

    Positions by cubic Hermite with the re-simulated velocities as slopes,
    the rest linearly.
    """
    y = np.asarray(cols[column], dtype=float)
    slope = SLOPES.get(column)
    v = None if slope is None else np.asarray(cols[slope], dtype=float) * (dt_ns / NS)
    return hermite(y, v, k, frac)


def hermite(y, v, k, frac):
    """
    Return ``y`` between its steps k and k + 1 at ``frac`` of the step.

    Cubic Hermite with the slopes ``v`` [unit per step] where given (a
    position and its velocity), else linear.
    """
    y0, y1 = y[k], y[k + 1]
    if v is None:
        return y0 + frac * (y1 - y0)
    s = frac
    s2 = s * s
    s3 = s2 * s
    return ((2 * s3 - 3 * s2 + 1) * y0 + (s3 - 2 * s2 + s) * v[k]
            + (-2 * s3 + 3 * s2) * y1 + (s3 - s2) * v[k + 1])


def at_times(cols, column, dt_ns, rel_ns, slope=False):
    """
    Return the re-simulated ``column`` at times ``rel_ns`` [ns] after the grid start.

    NaN outside the steps run. With ``slope`` also its time derivative [unit/s]
    (the velocity column of a position, else the difference quotient).
    """
    y = np.asarray(cols[column], dtype=float)
    n = len(y)
    kf = np.asarray(rel_ns, dtype=np.int64)
    k = kf // dt_ns - 1
    frac = (kf - (k + 1) * dt_ns) / dt_ns
    ok = (k >= 0) & (k < n - 1)
    out = np.full(len(kf), np.nan)
    out[ok] = between(cols, column, k[ok], frac[ok], dt_ns)
    if not slope:
        return out
    d = np.full(len(kf), np.nan)
    name = SLOPES.get(column)
    if name is not None:
        v = np.asarray(cols[name], dtype=float)
        d[ok] = v[k[ok]] + frac[ok] * (v[k[ok] + 1] - v[k[ok]])
    else:
        d[ok] = (y[k[ok] + 1] - y[k[ok]]) / (dt_ns / NS)
    return out, d
