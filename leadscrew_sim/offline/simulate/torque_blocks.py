"""
The torque blocks of a ``simulate`` run: torque commands [N m] through the node's hold.

An open-loop input (a function of time) runs a block in one compiled call,
a closed-loop one (reading the nut position [m] and motor-side nut speed
[m/s]) tick by tick; both hand the model the commands after the node's
:class:`~leadscrew_sim.core.commands.CommandHold` (loss, delay), as
``resim`` does.
"""
import numpy as np

from ..options import NS, RunError
from ...io import messages as M


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


def open_loop_block(model, hold, ks, dt_ns, torque_fn, forces):
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


def closed_loop_block(model, hold, ks, dt_ns, torque_fn, forces, x, vm, vm_scale):
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
