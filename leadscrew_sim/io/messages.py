"""
The state messages of one tick, encoded as the node publishes and records them.

The node, ``simulate`` and ``resim`` all encode their states through
:class:`StateEncoder`, so their files hold the same bytes. :data:`STATE_VALUES`
says which values of a tick each state topic carries: a new state topic is an
entry in :data:`leadscrew_sim.io.topics.TOPICS` and one here (with its
template in :data:`TEMPLATES`).
"""
from .cdr import clock_template, float64_template, joint_state_template, wrench_template

#: The values of one tick, in the order of ``LeadScrewModel.joint_values()``
#: and named as the columns of ``LeadScrewModel.run()``: rad, m, rad/s, m/s, N m, N, N m.
TICK_VALUES = ('screw_angle', 'nut_position', 'screw_velocity', 'nut_velocity', 'motor_torque',
               'axial_force', 'thread_torque')

#: State topic -> (stamped, the tick values its template takes, in order).
STATE_VALUES = {
    'joint_states': (True, ('screw_angle', 'nut_position', 'screw_velocity', 'nut_velocity',
                            'motor_torque', 'axial_force')),
    'nut_position': (False, ('nut_position',)),
    'thread_force': (True, ('axial_force', 'thread_torque')),
}

#: State topic -> template factory of the joint names (screw joint, nut joint).
TEMPLATES = {
    'joint_states': lambda joints: joint_state_template(joints, 2, 2, 2),
    'nut_position': lambda joints: float64_template(),
    'thread_force': lambda joints: wrench_template(),
}


class StateEncoder:
    """
    Encode the states of one tick, as the node publishes and records them.

    Joint names are ``<joint_prefix>screw_joint`` and ``<joint_prefix>nut_joint``.
    The templates are also attributes named as their topics, each called as
    ``(stamp_ns, values)``: ``joint_states(stamp, (screw_angle, nut_position,
    screw_velocity, nut_velocity, motor_torque, axial_force))``,
    ``nut_position(None, (x,))``, ``thread_force(stamp, (axial_force,
    thread_torque))`` and ``clock(stamp, ())``. Stamps are integer
    nanoseconds >= 0 (sec fits int32).

    Parameters
    ----------
    joint_prefix : str
        Prefix of the joint names.

    """

    def __init__(self, joint_prefix=''):
        """Build the byte templates for the joint names of ``joint_prefix``."""
        self.joint_prefix = joint_prefix
        self.joint_names = (joint_prefix + 'screw_joint', joint_prefix + 'nut_joint')
        self.templates = {t: make(self.joint_names) for t, make in TEMPLATES.items()}
        for topic, template in self.templates.items():
            setattr(self, topic, template)
        self.clock = clock_template()
        self._plan = tuple((topic, self.templates[topic], stamped,
                            tuple(TICK_VALUES.index(n) for n in names))
                           for topic, (stamped, names) in STATE_VALUES.items())

    def tick(self, stamp_ns, values):
        """
        Return [(topic, bytes)] of every state topic for one tick.

        Parameters
        ----------
        stamp_ns : int
            Stamp of the states [ns].
        values : sequence of float
            The tick's values in the order of :data:`TICK_VALUES`.

        """
        return [(topic, template(stamp_ns if stamped else None, [values[i] for i in index]))
                for topic, template, stamped, index in self._plan]

    def rows(self, stamps_ns, columns):
        """
        Return [(topic, uint8 rows)] of every state topic for many ticks at once.

        Parameters
        ----------
        stamps_ns : numpy.ndarray of int64
            Stamp of each tick [ns].
        columns : sequence of numpy.ndarray
            One array per value of :data:`TICK_VALUES`, in that order.

        """
        return [(topic, template.rows(stamps_ns if stamped else None,
                                      [columns[i] for i in index]))
                for topic, template, stamped, index in self._plan]

    @staticmethod
    def values(o):
        """Return the values of :data:`TICK_VALUES` of a StepOutput ``o``."""
        return tuple(getattr(o, name) for name in TICK_VALUES)
