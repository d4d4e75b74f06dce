"""
The ``simulate`` run: the model without ROS, recorded in the node's layout (an MCAP file).

Per tick k at t_k = k dt the file holds torque_command (and external_force
when it changes) logged at t_k, then the states logged at t_k + dt: the
node's rule (:data:`leadscrew_sim.core.commands.COMMAND_LOG_TIME`), so
``resim`` feeds the model the very same doubles and reproduces the states
bit for bit. The robot description and /tf_static come first (at t_0 = 0),
each tick's /tf after its states (then /clock with ``--clock``).
:func:`simulate` sets a run up from the options of ``leadscrew_sim
simulate`` and :func:`simulate_loop` runs it block by block.
"""
import dataclasses
import math
import sys
import time

import numpy as np

from ..options import (compression_of, gc_paused, load_params, NS, parse_sets, Progress,
                       RunError, simulation_faults)
from .sources import excite_profile, make_drive_source, make_force_source, make_torque_source
from ..run_events import EventLog
from .schedule import CLEAR_FAULT, read_schedule
from ...core.commands import CommandHold, DROPPED, INITIAL_COMMAND, NutMap
from ...core.delivery import StateDelivery
from ...core.drive_modes import FAULT_NONE
from ...core.fields import public_name
from ...core.params import ScrewParams
from ...io import cdr as C, messages as M
from ...io.run_file import (CLEAR_FAULT_RECORD, CLI_RECORD, PARAMS_RECORD, parameters_record,
                            RunWriter, UPDATE_RECORD)
from ...io.record_fill import Stamps
from ...io.tick_writer import Events, Stream, write_block
from ...analysis.excitation.commission import SEGMENTS_RECORD

#: Ticks per block: the model runs a block in one compiled call (open-loop
#: inputs) and the block's messages are encoded and recorded at once.
BLOCK_TICKS = 3000


@dataclasses.dataclass
class SimulatedRun:
    """
    What :func:`simulate` wrote.

    ``path``: the MCAP file; ``size`` its bytes; ``rate`` [Hz], ``steps`` and
    ``substeps`` (per step) of the run; ``simulated`` and ``wall`` its
    simulated and wall-clock time [s]; ``stats`` those of :func:`simulate_loop`;
    ``events`` the run's events (:func:`leadscrew_sim.analysis.events.run_events`).
    """

    path: str
    size: int
    rate: float
    steps: int
    substeps: int
    simulated: float
    wall: float
    stats: dict
    events: list = dataclasses.field(default_factory=list)


def simulate(args, warn):
    """
    Run the model offline as the options of ``simulate`` say and record it in the node's layout.

    Parameters
    ----------
    args : argparse.Namespace
        The options of ``leadscrew_sim simulate`` (``args.duration`` is set
        to the run's duration [s] when not given).
    warn : callable
        Told (a one-line text) of fault-schedule changes after the end of the run.

    Returns
    -------
    SimulatedRun

    Raises
    ------
    RunError
        For an invalid option or input, and when the integration fails
        (:class:`leadscrew_sim.core.faults.SimulationFault`).

    """
    with gc_paused():
        return _simulate(args, warn)


def _simulate(args, warn):
    """Set the run up from ``args``, run it and return its :class:`SimulatedRun`."""
    from ...core.model import LeadScrewModel
    phys_ov, run_ov = parse_sets(args.set)
    params, label, extra = load_params(args, phys_ov)
    rate = args.rate if args.rate is not None else float(extra.get('update_rate', 1000.0))
    profile = excite_profile(args, params)
    if args.duration is None:
        args.duration = profile.duration if profile is not None else 1.0
    if not (math.isfinite(rate) and 1.0 <= rate <= 1e6):
        raise RunError(f'--update-rate {rate} Hz must lie in [1, 1e6]')
    if not (math.isfinite(args.duration) and args.duration > 0):
        raise RunError(f'--duration {args.duration} s must be > 0')
    prefix = run_ov.get('joint_prefix', extra.get('joint_prefix', ''))
    dt_ns = int(round(NS / rate))
    n_steps = int(round(args.duration * NS / dt_ns))
    drive = make_drive_source(args, params, profile)
    if drive is None:
        torque_fn, torque_desc = make_torque_source(args, params, profile)
    else:
        torque_fn, torque_desc = drive[0], drive[2]
    force_fn, force_desc = make_force_source(args)
    schedule = read_schedule(args.faults, params, dt_ns) if args.faults else []
    late = [k for k, _changes in schedule if k >= n_steps]
    if late:
        warn(f'--faults {args.faults}: {len(late)} change(s) at or after the end of the run '
             f'({args.duration:g} s) have no effect')
    log = EventLog(params, dt_ns)
    if schedule and schedule[0][0] == 0:   # changes at t = 0 are the run's parameters
        first = {n: v for n, v in schedule.pop(0)[1].items() if n != CLEAR_FAULT}
        log.change(0, first)                # nothing latched to clear at the start
        params = ScrewParams.from_dict(first, base=params)
    model = LeadScrewModel(params, dt=dt_ns / NS)
    if drive is not None and drive[1] == 'mixed':       # commission: a topic per part
        torque_fn = MixedInput(drive[0], model, prefix)
    elif drive is not None:
        torque_fn = DriveInput(drive[0], drive[1], model, prefix)
    out = args.output or f'runs/sim_{label}_{time.strftime("%Y%m%d-%H%M%S")}.mcap'
    w = RunWriter(out, prefix, clock=args.clock, params=params,
                  compression=compression_of(args))
    w.rec.add_metadata(PARAMS_RECORD, parameters_record(
        params, label, rate, dt_ns, {'joint_prefix': prefix} if prefix else None))
    w.rec.add_metadata(CLI_RECORD, {
        'command': 'simulate', 'argv': ' '.join(sys.argv[1:]), 'torque_input': torque_desc,
        'force_input': force_desc, 'steps': str(n_steps)})
    if hasattr(profile, 'record'):      # the commission profile's segments, for later tools
        w.rec.add_metadata(SEGMENTS_RECORD, profile.record())
    t_wall = time.perf_counter()
    try:
        w.write_description(0)
        with simulation_faults():
            stats = simulate_loop(model, n_steps, dt_ns, torque_fn, force_fn, w,
                                  Progress(n_steps, 'simulate', args.quiet), args.clock,
                                  schedule, log)
    finally:
        size = w.close()
    return SimulatedRun(out, size, rate, n_steps, model.nsub, n_steps * dt_ns / NS,
                        time.perf_counter() - t_wall, stats, log.events())


def simulate_loop(model, n_steps, dt_ns, torque_fn, force_fn, w, progress, clock=False,
                  schedule=(), log=None):
    """
    Advance ``n_steps`` steps of ``dt_ns`` [ns], recording command and states per tick.

    Blocks of :data:`BLOCK_TICKS` ticks, cut also where ``schedule`` ([(step,
    {name: value})]) changes parameters: open-loop torque inputs (functions of
    time only) run through ``model.run`` in one compiled call, the closed-loop
    ``move`` profile tick by tick; both give the same bits as ``model.advance``
    per tick. The commands pass through the node's :class:`CommandHold` (lost
    commands, command delay) and the sensor states through its
    :class:`StateDelivery` (delay, lost states). Returns the statistics x_min,
    x_max, x_end [m] and tq_max [N m]. An :class:`EventLog` ``log`` gets the
    scheduled changes and the columns of every block (with the drive's).
    """
    dt = dt_ns / NS
    needs_state = getattr(torque_fn, 'needs_state', False)
    hold = torque_fn.hold if isinstance(torque_fn, (DriveInput, MixedInput)) else CommandHold(
        '', 0.0, NutMap.of_model(model), params=model.params)
    line = StateDelivery(model.params)
    o = model.output()
    x, vm = o.nut_position, 0.0
    vm_scale = model.params.hand_sign * model.params.lead_ratio
    stats = dict(x_min=x, x_max=x, x_end=x, tq_max=0.0)
    force = 0.0
    cuts = sorted({k for k in range(0, n_steps, BLOCK_TICKS)}
                  | {k for k, _c in schedule if 0 < k < n_steps}
                  | set(torque_fn.cuts(dt_ns, n_steps) if isinstance(torque_fn, MixedInput)
                        else ()))
    changes_at = dict(schedule)
    for k0, k1 in zip(cuts, cuts[1:] + [n_steps]):
        if k0 in changes_at:
            _apply_changes(model, hold, line, changes_at[k0], w, k0 * dt_ns)
            if log is not None:
                log.change(k0, {n: v for n, v in changes_at[k0].items() if n != CLEAR_FAULT})
        ks = range(k0, k1)
        forces, changes = _forces(force_fn, ks, dt, force)
        force = float(forces[-1])
        if isinstance(torque_fn, DriveInput):
            torques, cols = torque_fn.block(ks, dt_ns, forces)
        elif isinstance(torque_fn, MixedInput):
            torques, cols = torque_fn.block(ks, dt_ns, forces, x)
        elif needs_state:
            torques, cols = _closed_loop_block(model, hold, ks, dt_ns, torque_fn, forces, x, vm,
                                               vm_scale)
        else:
            torques, cols = _open_loop_block(model, hold, ks, dt_ns, torque_fn, forces)
        if log is not None:
            log.add(k0, cols)
        x = float(cols['nut_position'][-1])
        vm = vm_scale * model.output().motor_velocity
        _record_block(w, ks, dt_ns, torques, forces, changes, cols, clock, line)
        stats['x_min'] = min(stats['x_min'], float(np.min(cols['nut_position'])))
        stats['x_max'] = max(stats['x_max'], float(np.max(cols['nut_position'])))
        stats['tq_max'] = max(stats['tq_max'], float(np.max(np.abs(cols['motor_torque']))))
        stats['x_end'] = x
        progress.update(ks.stop)
    progress.done()
    return stats


def _forces(force_fn, ks, dt, before):
    """Return the external forces [N] of ticks ``ks`` and the ticks where the force changes."""
    if force_fn is None:
        return np.zeros(len(ks)), []
    forces = force_fn.block(np.arange(ks.start, ks.stop, dtype=np.int64) * dt)
    changed = np.flatnonzero(forces != np.concatenate([[before], forces[:-1]]))
    changes = [ks.start + int(i) for i in changed]
    if ks.start == 0 and 0 not in changes:
        changes.insert(0, 0)
    return forces, changes


def _apply_changes(model, hold, line, changes, w, log_time_ns):
    """
    Apply scheduled parameter changes before a step and record them as the node does.

    Then a scheduled :data:`~.schedule.CLEAR_FAULT` clears a latched drive fault
    (unless ``fault.drive_fault`` is true, as the node's ``~/clear_fault``), recorded
    as the node records it.
    """
    changes = dict(changes)
    clear = changes.pop(CLEAR_FAULT, False)
    if changes:
        params = ScrewParams.from_dict(changes, base=model.params)
        model.set_params(params)
        hold.set_faults(params)
        line.set_faults(params)
        record = {public_name(k): str(getattr(params, k)) for k in changes}
        record.update(log_time_ns=str(log_time_ns), messages_at_log_time='0')
        w.rec.add_metadata(UPDATE_RECORD, record)
    if clear and not model.params.fault_drive_fault and model.clear_fault() != FAULT_NONE:
        w.rec.add_metadata(CLEAR_FAULT_RECORD, {'log_time_ns': str(log_time_ns),
                                                'messages_at_log_time': '0'})


def _check_finite(torques, ks, dt):
    bad = np.flatnonzero(~np.isfinite(np.asarray(torques, dtype=float)))
    if len(bad):
        raise RunError(f'torque input is not finite at t={ks[bad[0]] * dt:.6f} s')


def _through_hold(hold, torques, ks, dt_ns, previous):
    """Return the torques the drive applies: the commands after loss and delay (as resim)."""
    applied = []
    for tq, k in zip(torques, ks):
        hold.torque_command(tq, k * dt_ns)
        command = hold.delayed(hold.command_at(k * dt_ns))
        previous = previous if command is None else command[3]
        applied.append(previous)
    return applied


def _count(hold, torques, ks, dt_ns):
    """Count commands that need no loss or delay, as received, and hold the last one."""
    if len(torques):
        hold.received += len(torques) - 1          # the drop counter counts every command
        hold.torque_command(torques[-1], ks[-1] * dt_ns)


def _open_loop_block(model, hold, ks, dt_ns, torque_fn, forces):
    """Run a block in one compiled call; return the torques and the run's columns."""
    dt = dt_ns / NS
    if hasattr(torque_fn, 'block'):
        torques = torque_fn.block(np.arange(ks.start, ks.stop, dtype=np.int64) * dt)
    else:
        torques = [float(torque_fn(k, k * dt, None, None)) for k in ks]
    _check_finite(torques, ks, dt)
    applied = torques
    if hold.delay or hold.drop_rate:
        applied = _through_hold(hold, torques, ks, dt_ns, model.held_torque())
    else:
        _count(hold, torques, ks, dt_ns)
    return torques, model.run(applied, forces, drive_values=True)


def _closed_loop_block(model, hold, ks, dt_ns, torque_fn, forces, x, vm, vm_scale):
    """Step tick by tick (the torque depends on the state); return torques and columns."""
    dt = dt_ns / NS
    n = len(ks)
    names = M.SENSOR_COLUMNS[:4] + M.TRUTH_VALUES + M.ANALYSIS_COLUMNS
    cols = {name: np.empty(n) for name in names}
    cols['fault'] = np.zeros(n, dtype=np.int8)
    switches = [np.zeros(n, dtype=bool) for _name in ('limit_min', 'limit_max', 'home')]
    cols.update(zip(('limit_min', 'limit_max', 'home'), switches))
    torques = []
    lossy = hold.delay or hold.drop_rate
    applied = model.held_torque()
    for i, k in enumerate(ks):
        tq = float(torque_fn(k, k * dt, x, vm))
        _check_finite([tq], [k], dt)
        torques.append(tq)
        if lossy:
            applied = _through_hold(hold, [tq], [k], dt_ns, applied)[0]
        else:
            applied = tq
            _count(hold, [tq], [k], dt_ns)
        model.advance(applied, None, forces[i])
        for name, v in zip(names, model.joint_values()[:4] + model.truth_values()
                           + model.analysis_values()):
            cols[name][i] = v
        cols['fault'][i] = model.drive_fault()
        for flags, on in zip(switches, model.switches()):
            flags[i] = on == 1.0
        x, vm = cols['nut_position'][i], vm_scale * cols['motor_velocity'][i]
    return torques, cols


def _record_block(w, ks, dt_ns, torques, forces, changes, cols, clock, line):
    """Encode and write the messages of one block in the node's per-tick order."""
    t_cmd = np.arange(ks.start, ks.stop, dtype=np.int64) * dt_ns
    if isinstance(torques, tuple):            # a drive input: (topic, message rows)
        cmd = torques[1], w.ids[torques[0]]
    else:
        cmd = C.F64_TEMPLATE.rows(None, [np.asarray(torques, dtype=float)]), \
            w.ids['torque_command']
    sensed = {name: cols[col] for name, col in zip(M.SENSOR_VALUES, M.SENSOR_COLUMNS)}
    if line.delay or line.drop_rate or line.pending():   # the node's line, per tick
        _record_ticks(w, ks, dt_ns, cmd, forces, changes, sensed, cols, clock, line)
        return
    enc, ids = w.enc, w.ids
    t_state = t_cmd + dt_ns
    stamps = Stamps(t_state)                  # one stamp per tick, on each message
    states = (enc.encoded('sensor', stamps, sensed) + enc.encoded('truth', stamps, cols)
              + enc.encoded('analysis', stamps, _analysis(cols)))
    st_rows = [r for _topic, r in states]
    st_chans = [ids[topic] for topic, _r in states]
    if w.tf is not None:
        st_rows.append(w.tf_rows(stamps, sensed['screw_angle'], sensed['nut_position']))
        st_chans.append(ids['/tf'])
    if clock:
        st_rows.append(enc.clock.rows(t_state, []))
        st_chans.append(ids['/clock'])
    write_block(w.rec, _command_pieces(w, cmd, t_cmd, forces, [c - ks.start for c in changes]),
                st_chans, st_rows, t_state)


def _analysis(cols):
    """Return the analysis values of a block's columns, by message field (floats)."""
    return {name: np.asarray(cols[col], dtype=float)
            for name, col in zip(M.ANALYSIS_VALUES, M.ANALYSIS_COLUMNS)}


def _command_pieces(w, cmd, t_cmd, forces, changed):
    """
    Return the tick_writer pieces of a block's commands: one per tick, forces where they change.

    ``changed``: block indices of the ticks whose force changed (written after
    their command).
    """
    cmd_rows, cmd_chan = cmd
    pieces, a = [], 0
    for i in sorted(changed) + [len(t_cmd)]:
        if i > a:
            pieces.append(Stream(a, i, cmd_chan, cmd_rows[a:i], t_cmd[a:i]))
        if i < len(t_cmd):
            t = int(t_cmd[i])
            pieces.append(Events(i, [(cmd_chan, cmd_rows[i].tobytes(), t),
                                     (w.ids['external_force'], C.encode_float64(forces[i]), t)]))
        a = i + 1
    return pieces


def _record_ticks(w, ks, dt_ns, cmd, forces, changes, sensed, cols, clock, line):
    """Write a block tick by tick, the sensor states through the node's StateDelivery."""
    enc, ids = w.enc, w.ids
    changed = set(changes)
    sensor_names, truth_names = M.SENSOR_VALUES, M.TRUTH_VALUES
    analysis = _analysis(cols)
    for i, k in enumerate(ks):
        t_cmd, t_state = k * dt_ns, (k + 1) * dt_ns
        w.write(cmd[1], cmd[0][i].tobytes(), t_cmd)
        if k in changed:
            w.write(ids['external_force'], C.encode_float64(forces[i]), t_cmd)
        line.sample(k + 1, t_state, tuple(float(sensed[n][i]) for n in sensor_names))
        values = None
        for stamp, values in line.due(k + 1):
            for topic, data in enc.sensor(stamp, values):
                w.write(ids[topic], data, t_state)
        for topic, data in enc.truth(t_state, tuple(float(cols[n][i]) for n in truth_names)):
            w.write(ids[topic], data, t_state)
        for topic, data in enc.analysis(t_state, tuple(float(analysis[n][i])
                                                       for n in M.ANALYSIS_VALUES)):
            w.write(ids[topic], data, t_state)
        if values is not None:
            w.write_tf(stamp, values[0], values[1], t_state)
        if clock:
            w.write(ids['/clock'], enc.clock(t_state, ()), t_state)


class DriveInput:
    """
    A velocity or position input through the drive, run block-wise in one compiled call.

    Each tick's command goes through :class:`CommandHold`, the rules the node
    and ``resim`` apply to the recorded message, so all three hand the model
    the same doubles; the messages are recorded on ``topic``.
    """

    def __init__(self, fn, topic, model, prefix):
        """Keep the source ``fn(t) -> (x, v)``, the command topic and the model."""
        self.fn, self.topic, self.model = fn, topic, model
        self.hold = CommandHold(prefix, 0.0, NutMap.of_model(model), params=model.params)
        self.joint = prefix + 'nut_joint'
        self.template = C.joint_state_template([self.joint], 1, 1, 0)
        self.previous = INITIAL_COMMAND     # the command the drive holds (delayed commands)

    def block(self, ks, dt_ns, forces):
        """Run ticks ``ks``; return ((topic, message rows), the run's columns)."""
        t_ns = np.arange(ks.start, ks.stop, dtype=np.int64) * dt_ns
        if hasattr(self.fn, 'block'):
            xs, vs = self.fn.block(t_ns / NS)
        else:
            xs, vs = np.empty(len(ks)), np.empty(len(ks))
            for i, t in enumerate(t_ns.tolist()):
                xs[i], vs[i] = self.fn(t / NS)
        commands = None
        if self.topic != 'joint_commands':
            commands = self.hold.take_series(
                self.topic, vs if self.topic == 'velocity_command' else xs, t_ns)
        if commands is None:
            commands = self._one_by_one(t_ns, xs, vs)
        self.previous = tuple(commands[-1])
        r = self.model.run(None, forces, commands=commands)
        t_cmd = t_ns
        if self.topic == 'joint_commands':
            rows = self.template.rows(t_cmd, [xs, vs])
        else:
            rows = C.F64_TEMPLATE.rows(None, [vs if self.topic == 'velocity_command' else xs])
        return (self.topic, rows), r

    def _one_by_one(self, t_ns, xs, vs):
        """Return the drive commands of the ticks at ``t_ns``, each through CommandHold."""
        commands = np.empty((len(t_ns), 4))
        hold, previous = self.hold, self.previous
        for i, t in enumerate(t_ns.tolist()):
            if self.topic == 'velocity_command':
                reason = hold.velocity_command(float(vs[i]), t)
            elif self.topic == 'position_command':
                reason = hold.position_command(float(xs[i]), t)
            else:
                reason = hold.joint_commands([self.joint], [xs[i]], [vs[i]], [], t)[1]
            if reason and reason is not DROPPED:
                raise RunError(f'drive input at t={t / NS:.6f} s: {reason}')
            command = hold.delayed(hold.command_at(t))
            previous = previous if command is None else command
            commands[i] = previous
        return commands


class MixedInput:
    """
    The commission profile: each part on its own command topic, all through one CommandHold.

    A velocity or position part runs block-wise as :class:`DriveInput`; the
    breakaway part (torque) tick by tick, its controller reading the nut
    position. Blocks are cut at the parts' first ticks (:meth:`cuts`), so
    each block's commands go on one topic.
    """

    def __init__(self, profile, model, prefix):
        """Keep the profile, its controller and the model."""
        self.profile, self.model = profile, model
        self.hold = CommandHold(prefix, 0.0, NutMap.of_model(model), params=model.params)
        self.ctl = profile.controller()
        self.previous = INITIAL_COMMAND

    def cuts(self, dt_ns, n_steps):
        """Return the first tick of every part after the first (within the run)."""
        out = []
        for _name, t0, _part in self.profile.parts[1:]:
            k = int(math.ceil(t0 * NS / dt_ns - 1e-6))
            if 0 < k < n_steps:
                out.append(k)
        return out

    def block(self, ks, dt_ns, forces, x):
        """Run ticks ``ks`` of one part; return the commands (as recorded) and the columns."""
        t_ns = np.arange(ks.start, ks.stop, dtype=np.int64) * dt_ns
        ts = t_ns / NS
        _name, t0, part = self.profile.part_at(float(ts[0]))
        if part.kind == 'torque':
            return self._torque_ticks(t_ns, forces, x)
        values = part.values(ts - t0)
        commands = self.hold.take_series(part.topic, values, t_ns)
        if commands is None:
            commands = self._one_by_one(part.topic, values, t_ns)
        self.previous = tuple(commands[-1])
        cols = self.model.run(None, forces, commands=commands)
        return (part.topic, C.F64_TEMPLATE.rows(None, [values])), cols

    def _take(self, topic, value, t):
        """Give one command to the hold; return the drive command in force at ``t`` [ns]."""
        take = getattr(self.hold, topic)
        reason = take(value, t)
        if reason and reason is not DROPPED:
            raise RunError(f'commission input at t={t / NS:.6f} s: {reason}')
        command = self.hold.delayed(self.hold.command_at(t))
        self.previous = self.previous if command is None else tuple(command)
        return self.previous

    def _one_by_one(self, topic, values, t_ns):
        """Return the drive commands of the ticks at ``t_ns``, each through CommandHold."""
        return np.array([self._take(topic, float(v), t) for v, t in zip(values, t_ns.tolist())])

    def _torque_ticks(self, t_ns, forces, x):
        """Step the torque part tick by tick (its controller reads the nut position x [m])."""
        torques, parts = [], []
        for i, t in enumerate(t_ns.tolist()):
            tq = float(self.ctl(t / NS, x))
            torques.append(tq)
            row = self._take('torque_command', tq, t)
            r = self.model.run(None, forces[i:i + 1], commands=[row])
            parts.append(r)
            x = float(r['nut_position'][-1])
        return torques, {k: np.concatenate([p[k] for p in parts]) for k in parts[0]}
