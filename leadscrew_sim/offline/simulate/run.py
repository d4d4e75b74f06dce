"""
The ``simulate`` run: the model without ROS, recorded in the node's layout (an MCAP file).

Per tick k at t_k = k dt the file holds torque_command (and external_force
when it changes) logged at t_k, then the states logged at t_k + dt: the
node's rule (:data:`leadscrew_sim.core.commands.COMMAND_LOG_TIME`), so
``resim`` feeds the model the very same doubles and reproduces the states
bit for bit. The robot description and /tf_static come first (at t_0 = 0),
each tick's /tf after its states (then /clock with the ``clock`` option).
:func:`simulate` sets a run up from the options of ``leadscrew_sim
simulate`` and :func:`simulate_loop` runs it block by block: a torque block
through :mod:`.torque_blocks`, a drive block through :mod:`.drive_inputs`,
each block's messages written by :mod:`.block_records`.
"""
import dataclasses
import math
import sys
import time

import numpy as np

from ..options import (compression_of, gc_paused, load_params, NS, parse_sets, Progress,
                       RunError, simulation_faults)
from .block_records import record_block
from .drive_inputs import DriveInput, MixedInput
from .sources import excite_profile, make_drive_source, make_force_source, make_torque_source
from ..run_events import EventLog
from .schedule import CLEAR_FAULT, read_schedule
from .torque_blocks import closed_loop_block, open_loop_block
from ...core.commands import CommandHold, NutMap
from ...core.delivery import StateDelivery
from ...core.drive_modes import FAULT_NONE
from ...core.fields import public_name
from ...core.params import ScrewParams
from .ageing_from import ageing_at_end
from ...io.run_file import (AGEING_END_RECORD, ageing_record, CLEAR_FAULT_RECORD, CLI_RECORD,
                            PARAMS_RECORD, parameters_record,
                            RunWriter, UPDATE_RECORD)
from ...analysis.excitation.commission import SEGMENTS_RECORD

__all__ = ['BLOCK_TICKS', 'DriveInput', 'MixedInput', 'simulate', 'simulate_loop',
           'SimulatedRun']

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
        Told (a one-line text) of fault-schedule changes after the end of the run; the
        text names an option as ``<<keyword>>`` (:func:`..options.option_text`).

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
        raise RunError(f'<<update_rate>> {rate} Hz must lie in [1, 1e6]')
    if not (math.isfinite(args.duration) and args.duration > 0):
        raise RunError(f'<<duration>> {args.duration} s must be > 0')
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
        warn(f'<<faults>> {args.faults}: {len(late)} change(s) at or after the end of the run '
             f'({args.duration:g} s) have no effect')
    log = EventLog(params, dt_ns)
    if schedule and schedule[0][0] == 0:   # changes at t = 0 are the run's parameters
        first = {n: v for n, v in schedule.pop(0)[1].items() if n != CLEAR_FAULT}
        log.change(0, first)                # nothing latched to clear at the start
        params = ScrewParams.from_dict(first, base=params)
    ageing = None
    if getattr(args, 'ageing_from', None):
        ageing = ageing_at_end(args.ageing_from, params)
    model = LeadScrewModel(params, dt=dt_ns / NS, ageing=ageing)
    if drive is not None and drive[1] == 'mixed':       # commission: a topic per part
        torque_fn = MixedInput(drive[0], model, prefix)
    elif drive is not None:
        torque_fn = DriveInput(drive[0], drive[1], model, prefix)
    out = args.output or f'runs/sim_{label}_{time.strftime("%Y%m%d-%H%M%S")}.mcap'
    w = RunWriter(out, prefix, clock=args.clock, params=params,
                  compression=compression_of(args))
    w.rec.add_metadata(PARAMS_RECORD, dict(parameters_record(
        params, label, rate, dt_ns, {'joint_prefix': prefix} if prefix else None),
        **ageing_record(model.ageing_state())))
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
        w.rec.add_metadata(AGEING_END_RECORD, dict(
            log_time_ns=str(n_steps * dt_ns), **ageing_record(model.ageing_state())))
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
            torques, cols = closed_loop_block(model, hold, ks, dt_ns, torque_fn, forces, x, vm,
                                              vm_scale)
        else:
            torques, cols = open_loop_block(model, hold, ks, dt_ns, torque_fn, forces)
        if log is not None:
            log.add(k0, cols)
        x = float(cols['nut_position'][-1])
        vm = vm_scale * model.output().motor_velocity
        record_block(w, ks, dt_ns, torques, forces, changes, cols, clock, line)
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
