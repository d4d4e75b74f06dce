"""
The recording of a ``simulate`` block: its messages in the node's per-tick order.

Commands are logged at t_k = k dt [ns], the states at t_k + dt; a block
without state delay or loss is encoded in one go (:mod:`leadscrew_sim.io.tick_writer`),
one with them tick by tick through the node's
:class:`~leadscrew_sim.core.delivery.StateDelivery`.
"""
import numpy as np

from ...io import cdr as C, messages as M
from ...io.record_fill import Stamps
from ...io.tick_writer import Events, Stream, write_block


def record_block(w, ks, dt_ns, torques, forces, changes, cols, clock, line):
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
