"""
The measured states of a foreign recording: JointState messages placed by their header stamps.

A robot's ``/joint_states`` (joint_state_broadcaster's) come at irregular
intervals, with gaps where messages were dropped, stamped in wall-clock
epoch time. They are kept as they are: one row per message, its stamp [ns],
and per joint the position, velocity and effort it carries (NaN where the
message has none: any number of joints, any of the three arrays, empty
arrays). Stamps that run backwards are an error; a repeated stamp keeps the
later message.
"""
import numpy as np

from ..options import NS, RunError
from ...io import cdr as C
from ...io import joint_states as JS

#: The measured signals of a JointState: (name, joint role, array, model.run column, unit).
SIGNALS = (('screw_angle', 'screw', 'position', 'sensor_screw_angle', 'rad'),
           ('screw_velocity', 'screw', 'velocity', 'sensor_screw_velocity', 'rad/s'),
           ('motor_torque', 'screw', 'effort', 'motor_torque', 'N m'),
           ('nut_position', 'nut', 'position', 'sensor_nut_position', 'm'),
           ('nut_velocity', 'nut', 'velocity', 'sensor_nut_velocity', 'm/s'),
           ('axial_force', 'nut', 'effort', 'axial_force', 'N'))

#: The unit of each measured signal.
UNITS = {s[0]: s[4] for s in SIGNALS}

#: The model.run column of each measured signal.
COLUMNS = {s[0]: s[3] for s in SIGNALS}


class States:
    """
    The mapped joints' measured values, by stamp.

    Attributes
    ----------
    stamps : numpy.ndarray of int64
        Header stamps [ns], increasing (repeats removed: the later message kept).
    log_times : numpy.ndarray of int64
        When each message was recorded [ns].
    values : dict
        Signal name (of :data:`SIGNALS`) -> float array like ``stamps``, NaN where
        a message had no value; only signals some message has.
    names : list of str
        The joint names of the first message.
    repeated : int
        Messages dropped for a repeated stamp.

    """

    def __init__(self, topic, arrays, screw, nut, path=''):
        """Decode ``arrays`` (TopicArrays of ``topic``) for joints ``screw`` and ``nut``."""
        if not len(arrays.log_times):
            raise RunError(f'{path}: no messages on the state topic {topic}')
        try:
            stamps, names, pos, vel, eff = JS.joint_state_columns(arrays.data)
        except C.DecodeError as exc:
            raise RunError(f'{path}: a message on {topic} is not a sensor_msgs/JointState '
                           f'({exc})') from None
        self.names = list(names)
        cols = {}
        for joint, role in ((screw, 'screw'), (nut, 'nut')):
            if joint is None:
                continue
            if joint not in names:
                raise RunError(f'<<{role}_joint>> {joint}: no such joint in the states on '
                               f'{topic} (joints: {", ".join(names) or "none"})')
            j = names.index(joint)
            for name, r, array, _col, _u in SIGNALS:
                if r == role:
                    got = {'position': pos, 'velocity': vel, 'effort': eff}[array][:, j]
                    if np.isfinite(got).any():
                        cols[name] = got
        if not cols:
            raise RunError(f'{path}: the states on {topic} carry no position, velocity or '
                           f'effort of {" or ".join(j for j in (screw, nut) if j)}')
        back = np.flatnonzero(np.diff(stamps) < 0)
        if len(back):
            i = int(back[0])
            raise RunError(f'{path}: the header stamps on {topic} run backwards at message '
                           f'{i + 1} ({stamps[i] / NS:.9f} s, then {stamps[i + 1] / NS:.9f} s); '
                           f'{len(back)} times in all')
        keep = np.append(stamps[1:] != stamps[:-1], True)
        self.repeated = int(np.count_nonzero(~keep))
        self.stamps = stamps[keep]
        self.log_times = np.asarray(arrays.log_times)[keep]
        self.values = {k: v[keep] for k, v in cols.items()}
        if not self.stamps[0]:
            raise RunError(f'{path}: the states on {topic} have zero header stamps')

    def __len__(self):
        """Return the number of states."""
        return len(self.stamps)

    def intervals(self):
        """Return (median, min, max) interval between stamps [s]."""
        d = np.diff(self.stamps) / NS
        if not len(d):
            return (float('nan'),) * 3
        return float(np.median(d)), float(d.min()), float(d.max())

    def gaps(self):
        """Return the number of intervals longer than 1.5 median ones (dropped messages)."""
        d = np.diff(self.stamps)
        return int(np.count_nonzero(d > 1.5 * np.median(d))) if len(d) else 0
