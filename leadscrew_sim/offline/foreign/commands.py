"""
The commands of a foreign recording: decoded by type and sampled on the step grid.

- ``std_msgs/Float64``: one value, what ``command_kind`` says (motor torque
  [N m], nut velocity [m/s] or nut position [m]).
- ``std_msgs/Float64MultiArray`` (forward_command_controller): entry
  ``command_index`` of ``data``, of ``command_kind``.
- ``sensor_msgs/JointState``: the position, velocity and effort of
  ``command_joint``, through the node's mode rule (:class:`CommandHold`).
- ``trajectory_msgs/JointTrajectory`` (joint_trajectory_controller): the
  position of ``command_joint`` sampled at every step as the controller
  samples it: the points lie at the header stamp (in the states' clock; the
  receipt time plus the delay when the stamp is zero) plus their
  ``time_from_start``; between two points linear in
  position, cubic Hermite where both carry velocities; from the receipt to
  the first point from the position (and velocity) held then; after the last
  point its position held. A new trajectory replaces the old one from its
  receipt. Accelerations are not used (the controller's quintic segments
  are taken as cubic).

A command is placed at its log time (its receipt) plus the command-to-state
delay and acts from the first step that starts at or after then
(:func:`leadscrew_sim.core.commands.first_step`). A non-finite value is
counted and skipped, as the node rejects it.
"""
import copy

import numpy as np

from .mapping import FLOAT64, JOINT_STATE, MULTI_ARRAY, TRAJECTORY
from ..options import NS, RunError
from ...core.commands import first_step
from ...core.drive_modes import MODE_POSITION, MODE_TORQUE
from ...io import cdr as C
from ...io import joint_states as JS

_NAN = float('nan')


class Commands:
    """
    The decoded commands of the mapped command topic.

    Attributes
    ----------
    times : numpy.ndarray of int64
        Receipt (log) time of each kept command [ns].
    kind : str
        ``scalar`` (Float64, Float64MultiArray), ``joint`` (JointState) or
        ``trajectory``.
    skipped : int
        Commands not taken: non-finite values (as the node rejects them).
    role : str
        ``screw`` or ``nut``: the joint a JointState or trajectory command moves
        (of the first command; ``roles`` has each JointState command's).

    """

    def __init__(self, topic, ctype, arrays, mapping, joints, path=''):
        """Decode the messages ``arrays`` (TopicArrays) of ``topic`` of type ``ctype``."""
        self.topic, self.ctype, self.path = topic, ctype, path
        self.command_kind = mapping.command_kind
        self.skipped = 0
        self.role = None
        datas = arrays.messages()
        times = np.asarray(arrays.log_times, dtype=np.int64)
        if not len(datas):
            raise RunError(f'{path}: no messages on the command topic {topic}')
        try:
            if ctype in (FLOAT64, MULTI_ARRAY):
                self._scalars(ctype, datas, times, mapping)
            elif ctype == JOINT_STATE:
                self._joint_states(datas, times, mapping, joints)
            elif ctype == TRAJECTORY:
                self._trajectories(datas, times, mapping, joints)
            else:
                raise RunError(f'<<command_topic>> {topic}: type {ctype!r} is not read (read: '
                               f'{", ".join((FLOAT64, MULTI_ARRAY, JOINT_STATE, TRAJECTORY))})')
        except C.DecodeError as exc:
            raise RunError(f'{path}: a message on {topic} is not a valid {ctype} '
                           f'({exc})') from None
        if not len(self.times):
            raise RunError(f'{path}: no finite commands on {topic} ({self.skipped} '
                           'non-finite skipped)')

    def _scalars(self, ctype, datas, times, mapping):
        if self.command_kind is None:
            raise RunError(f'<<command_kind>>: give torque, velocity or position for the '
                           f'{ctype.split("/")[-1]} topic {self.topic}')
        self.kind = 'scalar'
        if ctype == FLOAT64:
            values = C.decode_float64s(datas)
        else:
            index = mapping.command_index if mapping.command_index is not None else 0
            values = np.empty(len(datas))
            table = C.decode_float64_multi_arrays(datas)
            if table is not None and index < table.shape[1]:
                values = table[:, index].copy()
                datas = []              # read at once: nothing left to decode
            for i, d in enumerate(datas):
                a = C.decode_float64_multi_array(bytes(d))
                if index >= len(a):
                    raise RunError(f'<<command_index>> {index}: past the array of message {i} on '
                                   f'{self.topic} ({len(a)} entries: give 0 .. {len(a) - 1})')
                values[i] = a[index]
        ok = np.isfinite(values)
        self.skipped = int(np.count_nonzero(~ok))
        self.times, self.values = times[ok], values[ok]

    def _joint(self, names, mapping, joints):
        """Return (the command joint's name, its role) among the command's ``names``."""
        screw, nut = joints
        name = mapping.command_joint
        if name is None:
            name = nut if nut in names else screw if screw in names else None
            if name is None:
                raise RunError(f'<<command_joint>>: the commands on {self.topic} name '
                               f'{", ".join(names) or "no joint"}; give the one to take')
        if name not in names:
            raise RunError(f'<<command_joint>> {name}: not in the commands on {self.topic} '
                           f'(joints: {", ".join(names) or "none"})')
        if name not in (screw, nut):
            raise RunError(f'<<command_joint>> {name}: is neither <<screw_joint>> {screw} nor '
                           f'<<nut_joint>> {nut}')
        return name, 'nut' if name == nut else 'screw'

    def _joint_states(self, datas, times, mapping, joints):
        """
        Keep each message's (position, velocity, effort) of its mapped joint.

        With ``command_joint`` only that joint's values are taken; without,
        each message's own joint: the nut joint where it names it, else the
        screw joint (the node takes a torque on the screw joint and a nut
        position or velocity on the nut joint, one joint per message).
        """
        self.kind = 'joint'
        screw, nut = joints
        groups = JS.joint_state_groups(datas)
        first = next(g for g in groups if g[0][0] == 0)
        _name, self.role = self._joint(first[1], mapping, joints)  # the first message's
        n = len(datas)
        values = np.full((n, 3), _NAN)
        roles = np.empty(n, dtype=object)
        for index, names, *arrays in groups:
            if mapping.command_joint is not None:
                name, role = self._joint(names, mapping, joints)
            elif nut in names:
                name, role = nut, 'nut'
            elif screw in names:
                name, role = screw, 'screw'
            else:
                continue            # a message that names neither joint is skipped
            j = names.index(name)
            for col, a in enumerate(arrays):
                if j < a.shape[1]:
                    values[index, col] = a[:, j]
            roles[index] = role
        keep = np.isfinite(values).any(axis=1)
        self.skipped += int(np.count_nonzero(~keep))
        self.times = np.asarray(times, dtype=np.int64)[keep]
        self.values = values[keep]
        self.roles = list(roles[keep])

    def _trajectories(self, datas, times, mapping, joints):
        self.kind = 'trajectory'
        name = None
        self.trajectories, kept = [], []
        for t, d in zip(times, datas):
            stamp, names, points = C.decode_joint_trajectory(bytes(d))
            if name is None:
                name, self.role = self._joint(names, mapping, joints)
            if name not in names or not points:
                self.skipped += 1
                continue
            j = names.index(name)
            at = np.array([(stamp if stamp else 0) + p[4] for p in points], dtype=np.int64)
            pos = np.array([p[0][j] if j < len(p[0]) else _NAN for p in points])
            vel = np.array([p[1][j] if j < len(p[1]) else _NAN for p in points])
            if not np.isfinite(pos).all() or (np.diff(at) <= 0).any():
                self.skipped += 1
                continue
            self.trajectories.append((at, pos, vel if np.isfinite(vel).all() else None,
                                      not stamp))
            kept.append(t)
        self.times = np.array(kept, dtype=np.int64)

    def by_kind(self, nut_map, delay_ns=0):
        """
        Return {kind: (times [ns], values)} of the commands as the node takes them.

        Kinds ``torque`` [N m], ``velocity`` [m/s of the nut] and ``position``
        [m of the nut]: a JointState command is the position where it gives
        one, else the velocity, else the effort (the node's mode rule), its
        screw values mapped onto the nut by ``nut_map`` (a nut effort [N] onto
        the motor torque); a trajectory's points at their times. ``delay_ns``
        moves the receipt times as the re-simulation does.
        """
        out = {k: ([], []) for k in ('torque', 'velocity', 'position')}
        if self.kind == 'scalar':
            out[self.command_kind] = (list(self.times + delay_ns), list(self.values))
        elif self.kind == 'joint':
            for t, (p, v, e), role in zip(self.times, self.values, self.roles):
                nut = role == 'nut'
                if p == p:
                    kind, x = 'position', p if nut else nut_map.x0 + (p - nut_map.theta0) / \
                        nut_map.k
                elif v == v:
                    kind, x = 'velocity', v if nut else v / nut_map.k
                else:
                    kind, x = 'torque', nut_map.effort(e) if nut else e
                out[kind][0].append(int(t) + delay_ns)
                out[kind][1].append(float(x))
        else:
            for i, (at, pos, _vel, relative) in enumerate(self.trajectories):
                at = at + (int(self.times[i]) + delay_ns if relative else 0)
                x = pos if self.role == 'nut' else nut_map.x0 + (pos - nut_map.theta0) / \
                    nut_map.k
                out['position'][0].extend(int(a) for a in at)
                out['position'][1].extend(float(v) for v in x)
        return {k: (np.array(ts, dtype=np.int64), np.array(vs, dtype=float))
                for k, (ts, vs) in out.items()}

    def rate(self):
        """Return the median command rate [Hz] (0 for a single command)."""
        if self.kind == 'trajectory' or len(self.times) < 2:
            return 0.0
        d = np.diff(self.times)
        d = d[d > 0]
        return float(NS / np.median(d)) if len(d) else 0.0

    def span(self):
        """Return (first, last) time a command sets [ns]: receipts, or the trajectories' ends."""
        last = int(self.times[-1])
        if self.kind == 'trajectory':
            last = max(last, max(int(a[-1]) + (int(t) if relative else 0) for t, (
                a, _p, _v, relative) in zip(self.times, self.trajectories)))
        return int(self.times[0]), last

    def rows(self, t0, dt_ns, n, hold, delay_ns, start=None):
        """
        Return the drive commands (n, 4) of steps 0 .. n - 1 of the grid from ``t0`` [ns].

        ``hold`` (a :class:`CommandHold`) applies the node's rules and maps
        nut values to the motor; ``delay_ns`` shifts every command; ``start``
        is the position [m or rad] held before the first trajectory point.
        Steps before the first command hold zero torque.
        """
        rows = np.empty((n, 4))
        rows[:] = (MODE_TORQUE, _NAN, _NAN, 0.0)
        if n <= 0:
            return rows
        ks = first_step(self.times + delay_ns, t0, dt_ns)
        if self.kind == 'scalar':
            cmd = hold.take_series(f'{self.command_kind}_command', self.values, self.times)
            if cmd is None:
                cmd = np.array([_one(hold, f'{self.command_kind}_command', v, int(t))
                                for v, t in zip(self.values, self.times)]).reshape(-1, 4)
            return _held(rows, ks, cmd)
        if self.kind == 'joint':
            cmd = np.empty((len(self.times), 4))
            for i, (t, (p, v, e), role) in enumerate(zip(self.times, self.values, self.roles)):
                label = 'nut_joint' if role == 'nut' else 'screw_joint'
                hold.joint_commands([label], [p], [v], [e], int(t))
                cmd[i] = hold.command_at(int(t))
            return _held(rows, ks, cmd)
        targets = self.sample(t0, dt_ns, n, ks, delay_ns, start)
        ok = np.isfinite(targets)
        if self.role == 'nut':
            theta = hold.nut_map.position(targets[ok])
        else:
            theta = targets[ok]
        rows[ok] = (MODE_POSITION, 0.0, _NAN, 0.0)
        rows[ok, 1] = theta
        return rows

    def sample(self, t0, dt_ns, n, ks, delay_ns=0, start=None):
        """
        Return the trajectories' position [m or rad] at each step's start (NaN before the first).

        Step k samples at ``t0 + k dt`` (the states' clock); trajectory i is in
        force from step ``ks[i]`` until the next one's. Stamped points lie at
        their stamp (the states' clock, as the robot's controller samples them);
        the points of a trajectory with a zero stamp from its receipt plus the
        delay.
        """
        out = np.full(n, _NAN)
        held_p, held_v = (start if start is not None else _NAN), 0.0
        for i, (at, pos, vel, relative) in enumerate(self.trajectories):
            if relative:
                at = at + int(self.times[i]) + delay_ns
            k0 = max(0, int(ks[i]))
            k1 = n if i + 1 == len(self.trajectories) else min(n, max(k0, int(ks[i + 1])))
            if k0 >= n:
                break
            if k1 <= k0:
                continue
            t = t0 + np.arange(k0, k1, dtype=np.int64) * dt_ns
            t_recv = t0 + k0 * dt_ns
            if not np.isfinite(held_p):
                held_p = pos[0]
            # the segment from the receipt to the first point starts at the held position
            if at[0] > t_recv:
                at_all = np.concatenate([[t_recv], at])
                pos_all = np.concatenate([[held_p], pos])
                vel_all = None if vel is None else np.concatenate([[held_v], vel])
            else:
                at_all, pos_all, vel_all = at, pos, vel
            out[k0:k1], last_v = _piecewise(t, at_all, pos_all, vel_all)
            held_p, held_v = out[k1 - 1], last_v
        return out


def _one(hold, kind, value, t):
    """Return the drive command row after one Float64 command through ``hold``."""
    getattr(hold, kind)(float(value), t)
    return hold.command_at(t)


def _held(rows, ks, cmd):
    """Fill ``rows`` from each command's first step on with its row (the last of a step wins)."""
    n = len(rows)
    steps = np.arange(n)
    idx = np.searchsorted(ks, steps, side='right') - 1
    ok = idx >= 0
    rows[ok] = cmd[idx[ok]]
    return rows


def _piecewise(t, at, pos, vel):
    """
    Return (positions at times ``t`` [ns], the velocity at the last of them) of one trajectory.

    Linear between points, cubic Hermite where ``vel`` is given; held before
    the first and after the last point.
    """
    out = np.empty(len(t))
    i = np.searchsorted(at, t, side='right') - 1
    before, after = i < 0, i >= len(at) - 1
    out[before] = pos[0]
    out[after] = pos[-1]
    mid = ~(before | after)
    j = i[mid]
    h = (at[j + 1] - at[j]) / NS
    s = (t[mid] - at[j]) / NS / h
    if vel is None:
        out[mid] = pos[j] + s * (pos[j + 1] - pos[j])
        slope = (pos[j + 1] - pos[j]) / h
    else:
        h00, h10 = 2 * s ** 3 - 3 * s ** 2 + 1, s ** 3 - 2 * s ** 2 + s
        h01, h11 = -2 * s ** 3 + 3 * s ** 2, s ** 3 - s ** 2
        out[mid] = h00 * pos[j] + h10 * h * vel[j] + h01 * pos[j + 1] + h11 * h * vel[j + 1]
        slope = ((6 * s ** 2 - 6 * s) * pos[j] + (3 * s ** 2 - 4 * s + 1) * h * vel[j]
                 + (-6 * s ** 2 + 6 * s) * pos[j + 1] + (3 * s ** 2 - 2 * s) * h * vel[j + 1]) / h
    last_v = 0.0
    if len(t) and mid[-1]:
        last_v = float(slope[-1])
    return out, last_v


class CommandSet:
    """
    The commands of several topics (a controller switch's): each acts from its time on.

    ros2_control's controller switching leaves the commands of each
    controller on its own topic; the active one's are the latest. Each topic
    is read as a :class:`Commands`; on the step grid the command in force is
    that of the topic whose latest command came last (ties: the later topic
    in the mapping's order). With one topic it is that topic's commands.

    Attributes
    ----------
    parts : list of Commands
    topic : str
        The topics, comma-separated (for messages).
    ctype : str
        Their types, comma-separated.

    """

    def __init__(self, parts):
        """Hold the decoded ``parts``, one per topic."""
        self.parts = list(parts)
        self.topic = ', '.join(p.topic for p in self.parts)
        self.ctype = ', '.join(p.ctype for p in self.parts)
        self.times = np.sort(np.concatenate([p.times for p in self.parts]))
        self.skipped = sum(p.skipped for p in self.parts)
        self.kind = self.parts[0].kind if len(self.parts) == 1 else 'several'
        self.role = next((p.role for p in self.parts if p.role is not None), None)

    def by_kind(self, nut_map, delay_ns=0):
        """Return {kind: (times [ns], values)} of every topic's commands, in time order."""
        out = {}
        for p in self.parts:
            for k, (ts, vs) in p.by_kind(nut_map, delay_ns).items():
                a, b = out.get(k, (np.zeros(0, np.int64), np.zeros(0)))
                out[k] = (np.concatenate([a, ts]), np.concatenate([b, vs]))
        for k, (ts, vs) in out.items():
            order = np.argsort(ts, kind='stable')
            out[k] = (ts[order], vs[order])
        return out

    def rate(self):
        """Return the fastest topic's median command rate [Hz]."""
        return max(p.rate() for p in self.parts)

    def span(self):
        """Return (first, last) time any topic's commands set [ns]."""
        spans = [p.span() for p in self.parts]
        return min(a for a, _b in spans), max(b for _a, b in spans)

    def rows(self, t0, dt_ns, n, hold, delay_ns, start=None):
        """Return the drive commands (n, 4) of the grid: each step the latest topic's row."""
        if len(self.parts) == 1:
            return self.parts[0].rows(t0, dt_ns, n, hold, delay_ns, start)
        rows = np.empty((n, 4))
        rows[:] = (MODE_TORQUE, _NAN, _NAN, 0.0)
        latest = np.full(n, -1, dtype=np.int64)     # time of the command in force [ns]
        steps = np.arange(n)
        for p in self.parts:        # each topic through its own copy of the node's rules
            mine = p.rows(t0, dt_ns, n, copy.deepcopy(hold), delay_ns, start)
            ks = first_step(p.times + delay_ns, t0, dt_ns)
            idx = np.searchsorted(ks, steps, side='right') - 1
            t_in_force = np.where(idx >= 0, p.times[np.maximum(idx, 0)], -1)
            take = (idx >= 0) & (t_in_force >= latest)
            rows[take] = mine[take]
            latest[take] = t_in_force[take]
        return rows
