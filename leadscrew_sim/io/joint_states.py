"""
JointState messages decoded in bulk: a broadcaster's states at once, mixed commands by layout.

The per-message decoder and the byte templates are :mod:`.cdr`'s; these
read many serialized messages through a template where their layout allows.
"""
import numpy as np

from .cdr import decode_joint_state, joint_state_template, NS


def joint_state_columns(messages):
    """
    Return (stamps [ns] (n,), names, (n, m) positions, velocities, efforts) of JointStates.

    When every message has the first one's names and array lengths (a
    broadcaster's states), they are read at once through a :class:`Template`;
    else message by message, an entry a message lacks (a short or empty
    array, a joint it does not name) is NaN. ``messages``: list of bytes or a
    uint8 array (n, L).
    """
    n = len(messages)
    if not n:
        return np.zeros(0, np.int64), [], np.zeros((0, 0)), np.zeros((0, 0)), np.zeros((0, 0))
    _s, names, pos, vel, eff = decode_joint_state(bytes(messages[0]))
    m = len(names)
    rows = messages if isinstance(messages, np.ndarray) else None
    if rows is None:
        lengths = {len(d) for d in messages}
        if len(lengths) == 1:
            rows = np.frombuffer(b''.join(messages), dtype=np.uint8).reshape(n, -1)
    if rows is not None:
        tmpl = joint_state_template(names, len(pos), len(vel), len(eff))
        got = tmpl.columns(rows)
        if got is not None:
            sec = np.ndarray((n,), dtype='<i4', buffer=np.ascontiguousarray(rows),
                             offset=tmpl.stamp_off, strides=(rows.shape[1],))
            nsec = np.ndarray((n,), dtype='<u4', buffer=np.ascontiguousarray(rows),
                              offset=tmpl.stamp_off + 4, strides=(rows.shape[1],))
            stamps = sec.astype(np.int64) * NS + nsec.astype(np.int64)
            out = []
            at = 0
            for length in (len(pos), len(vel), len(eff)):
                block = np.full((n, m), np.nan)
                block[:, :min(length, m)] = got[:, at:at + min(length, m)]
                at += length
                out.append(block)
            return (stamps, names, *out)
    stamps = np.empty(n, dtype=np.int64)
    out = [np.full((n, m), np.nan) for _ in range(3)]
    index = {name: j for j, name in enumerate(names)}
    for i, d in enumerate(messages):
        stamp, nm, *arrays = decode_joint_state(bytes(d))
        stamps[i] = stamp
        for j, name in enumerate(nm):
            col = index.get(name)
            if col is None:
                continue
            for block, a in zip(out, arrays):
                if j < len(a):
                    block[i, col] = a[j]
    return (stamps, names, *out)


def joint_state_groups(messages):
    """
    Return serialized JointStates ``messages`` decoded in groups of one layout.

    A list of (indices into ``messages`` (k,), names, positions (k, n_pos),
    velocities (k, n_vel), efforts (k, n_eff)) that holds every message once:
    the messages of one byte length that match the first one's layout
    (:meth:`Template.matching`: the same names and array lengths, an empty
    frame_id) are read at once, any other message on its own.
    """
    lengths = np.array([len(d) for d in messages], dtype=np.int64)
    out = []
    for length in np.unique(lengths):
        rest = np.flatnonzero(lengths == length)
        rows = np.frombuffer(b''.join(bytes(messages[i]) for i in rest),
                             dtype=np.uint8).reshape(len(rest), int(length))
        while len(rest):
            _s, names, pos, vel, eff = decode_joint_state(bytes(rows[0]))
            tmpl = joint_state_template(names, len(pos), len(vel), len(eff))
            same = tmpl.matching(rows)
            if not same[0]:             # a layout no template reads (a frame_id): alone
                same[:] = False
                same[0] = True
                got = np.array([list(pos) + list(vel) + list(eff)], dtype=float)
            else:
                got = tmpl.columns(rows[same])
            a, b = len(pos), len(pos) + len(vel)
            out.append((rest[same], names, got[:, :a], got[:, a:b], got[:, b:]))
            rest, rows = rest[~same], rows[~same]
    return out
