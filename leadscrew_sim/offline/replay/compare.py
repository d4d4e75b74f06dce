"""
The comparison of a re-simulation with its recording: the states, field by field.

:func:`compare` gives (topic, field, max |diff|, rms diff, n) rows in the
recorded units (rad, m, rad/s, m/s, N m, N) of joint_states, nut_position,
thread_force and sim/joint_states; it decodes each topic's recorded states
at once where their layout is the encoder's. :func:`compared_ticks` counts
the recorded ticks the re-simulation also has a state of.
"""
import math

import numpy as np

from ...io import cdr as C, messages as M


def compare(sim, new):
    """
    Return rows (topic, field, max |diff|, rms diff, n) of the new vs the recorded states.

    Also returns the number of compared values whose IEEE 754 bits differ (a
    zero difference can hide -0.0 against +0.0).

    Parameters
    ----------
    sim : Resim
        The re-simulation, with its recorded states.
    new : NewStates
        What :meth:`Resim.run` produced.

    """
    enc = M.StateEncoder(sim.prefix, sim.params.anti_backlash)
    screw, nut = sim.joint_labels()
    truth_plan = {topic: index for topic, _t, _s, index, _n in enc._plan['truth']}
    tables = [   # topic, field labels, recorded decoder, new values (n_steps + 1, m), has
        ('joint_states', [f'{q}[{j}]' for q in ('position', 'velocity', 'effort')
                          for j in (screw, nut)], _joint_states6, new.sensor,
         new.has_sensor),
        ('nut_position', ['data'], _float64s, new.sensor[:, [1]], new.has_sensor),
        ('thread_force', ['force.x', 'torque.x'], _wrench2, new.truth[:, [12, 9]],
         new.has_truth)]
    rows, bits = [], 0
    for topic, labels, decode, values, has in tables:
        got = _compared(sim, topic, decode, values, has)
        bits += _table_rows(rows, sim.topics.get(topic) or topic, labels, got)
    if 'sim/joint_states' in sim.states:
        index = list(truth_plan['sim/joint_states'])
        names, recorded = _truth_values(sim.states['sim/joint_states'][1])
        if names is not None:
            labels = [f'{q}[{name}]' for q in ('position', 'velocity', 'effort')
                      for name in names]
            ks = np.asarray(sim.states['sim/joint_states'][0])
            got = _pairs(ks, recorded, new.truth[:, index[:recorded.shape[1]]], new.has_truth)
            bits += _table_rows(rows, sim.topics.get('sim/joint_states'), labels, got)
    return rows, bits


def _compared(sim, topic, decode, values, has):
    """Return (recorded, new) value arrays of the steps where both have a state of a topic."""
    if topic not in sim.states:
        return None
    ks, datas = sim.states[topic]
    return _pairs(np.asarray(ks), decode(datas), values, has)


def _pairs(ks, recorded, values, has):
    """Return the recorded and the new values of the steps ``ks`` both have."""
    ks_in = ks < len(has)
    ok = np.zeros(len(ks), dtype=bool)
    ok[ks_in] = has[ks[ks_in]]
    if ok.all() and len(ks) and ks[-1] - ks[0] == len(ks) - 1 and (np.diff(ks) == 1).all():
        return recorded, values[ks[0]:ks[-1] + 1]       # every step of a stretch: views
    return recorded[ok], values[ks[ok]]


def _table_rows(rows, topic, labels, got):
    """Append a topic's rows (topic, field, max, rms, n); return its bit differences."""
    if got is None:
        return 0
    old, now = got
    d = np.abs(old - now)
    d[np.isnan(d)] = math.inf                   # a NaN on one side only, or on both
    n = len(d)
    bits = int(np.count_nonzero(old.view(np.int64) != now.view(np.int64)))
    if n:
        largest = d.max(axis=0)
        rms = np.sqrt(np.einsum('ij,ij->j', d, d) / n)
    for j, label in enumerate(labels):
        rows.append((topic, label, float(largest[j]) if n else 0.0,
                     float(rms[j]) if n else float('nan'), n))
    return bits


def _rows_of(datas):
    if isinstance(datas, np.ndarray):
        return datas
    lengths = {len(d) for d in datas}
    if len(lengths) != 1:
        return None
    return np.frombuffer(b''.join(datas), dtype=np.uint8).reshape(len(datas), -1)


def _joint_states6(datas):
    """Return (n, 6): the first two positions, velocities and efforts of each JointState."""
    rows = _rows_of(datas)
    if rows is not None:
        names = C.decode_joint_state(bytes(datas[0]))[1]
        got = C.joint_state_template(names, 2, 2, 2).columns(rows) if len(names) == 2 else None
        if got is not None:
            return got
    out = np.full((len(datas), 6), np.nan)
    for i, d in enumerate(datas):
        _s, _n, pos, vel, eff = C.decode_joint_state(bytes(d))
        for j, (a, b) in enumerate(((pos, 0), (pos, 1), (vel, 0), (vel, 1), (eff, 0),
                                    (eff, 1))):
            if len(a) > b:
                out[i, j] = a[b]
    return out


def _float64s(datas):
    """Return (n, 1): the data of each std_msgs/Float64."""
    return C.decode_float64s(datas).reshape(-1, 1)


def _wrench2(datas):
    """Return (n, 2): force.x and torque.x of each WrenchStamped."""
    rows = _rows_of(datas)
    got = C.wrench_template().columns(rows) if rows is not None else None
    if got is not None:
        return got
    out = [(f[0], t[0]) for _s, f, t in (C.decode_wrench_stamped(bytes(d)) for d in datas)]
    return np.array(out, dtype=float).reshape(-1, 2)


def _truth_values(datas):
    """Return (joint names, (n, 3 m) positions, velocities, efforts) of sim/joint_states."""
    if not len(datas):
        return None, None
    names = C.decode_joint_state(bytes(datas[0]))[1]
    m = len(names)
    rows = _rows_of(datas)
    got = C.joint_state_template(names, m, m, m).columns(rows) if rows is not None else None
    if got is None:
        got = np.full((len(datas), 3 * m), np.nan)
        for i, d in enumerate(datas):
            _s, nm, pos, vel, eff = C.decode_joint_state(bytes(d))
            if list(nm) == list(names) and len(pos) == len(vel) == len(eff) == m:
                got[i] = list(pos) + list(vel) + list(eff)
    return names, got


def compared_ticks(sim, new):
    """
    Return the number of recorded ticks for which the re-simulation has a state too.

    Parameters
    ----------
    sim : Resim
        The re-simulation, with its recorded states.
    new : NewStates
        What :meth:`Resim.run` produced.

    """
    has = new.has_sensor | new.has_truth
    recorded = np.zeros(len(has), dtype=bool)
    for ks, _d in sim.states.values():
        ks = np.asarray(ks, dtype=np.int64)
        recorded[ks[ks < len(has)]] = True
    return int(np.count_nonzero(recorded & has))
