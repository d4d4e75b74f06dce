"""
The drive inputs of a ``simulate`` run: velocity [m/s] and position [m] commands.

:class:`DriveInput` runs one command topic block-wise through the drive;
:class:`MixedInput` runs the commission profile, each part on its own topic.
Both pass every command through the node's
:class:`~leadscrew_sim.core.commands.CommandHold`.
"""
import math

import numpy as np

from ..options import NS, RunError
from ...core.commands import CommandHold, DROPPED, INITIAL_COMMAND, NutMap
from ...io import cdr as C


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
