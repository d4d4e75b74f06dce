"""What every stage of ``commission`` reads: the recording, its parts, the measured signals."""
import dataclasses

import numpy as np

from ..options import NS
from ...io import cdr as C


@dataclasses.dataclass
class Measured:
    """
    The recorded joint_states: the sensors as the axis reported them.

    ``time`` [s] (stamps), ``motor_torque`` [N m], ``motor_velocity``
    [rad/s], ``nut_position`` [m], ``nut_velocity`` [m/s].
    """

    time: np.ndarray
    motor_torque: np.ndarray
    motor_velocity: np.ndarray
    nut_position: np.ndarray
    nut_velocity: np.ndarray

    @classmethod
    def of(cls, rec):
        """Return the measured signals of a recording's joint_states (empty without)."""
        topic = rec.role_topic('joint_states')
        rows = []
        for _t, tp, data in rec.messages:
            if tp == topic:
                stamp, _n, pos, vel, eff = C.decode_joint_state(data)
                if len(pos) >= 2 and len(vel) >= 2 and eff:
                    rows.append((stamp / NS, eff[0], vel[0], pos[1], vel[1]))
        cols = [np.array(c) for c in zip(*rows)] if rows else [np.empty(0)] * 5
        return cls(*cols)

    def window(self, a, b):
        """Return the index mask of the samples in [a, b] [s]."""
        return (self.time >= a) & (self.time <= b)


@dataclasses.dataclass
class Context:
    """
    The inputs of the stages and what earlier stages found.

    ``path`` the recording, ``rec`` it opened, ``windows`` {part: (start,
    end) [s]}, ``commands`` {kind: (log times [s], values)}, ``measured``
    (:class:`Measured`), ``start`` the starting ScrewParams and ``label``
    their name, ``work`` a scratch directory, ``identify_args`` the options
    of ``identify`` (mapping flags), ``calibrated`` the ScrewParams after the
    fit, ``fit`` what :func:`fit_recording` returned (None: no fit),
    ``noise`` {signal: sigma} of the fit, ``twin`` the calibrated
    re-simulation's columns (or None), ``rate`` the step rate [Hz], ``axis``
    where the pieces came from (:mod:`.sources`: the recording's own or a
    mapped real axis), ``origin`` the log time [s] every time here counts
    from (0, or the start of a recording stamped in epoch time).
    """

    path: str
    rec: object
    windows: dict
    commands: dict
    measured: Measured
    start: object
    label: str
    work: str
    identify_args: object
    calibrated: object = None
    fit: dict = None
    noise: dict = dataclasses.field(default_factory=dict)
    twin: dict = None
    twin_time: np.ndarray = None
    fitted_on: list = dataclasses.field(default_factory=list)
    rate: float = 1000.0
    axis: object = None
    origin: float = 0.0

    def held(self, kind, t):
        """Return the command of ``kind`` in force at the times ``t`` [s] (NaN before any)."""
        from ...analysis.figures import hold_series
        ts, vs = self.commands[kind]
        return hold_series(ts, vs, t)
