"""
The state messages of one tick, encoded as the node publishes and records them.

The node, ``simulate`` and ``resim`` all encode their states through
:class:`StateEncoder`, so their files hold the same bytes. A tick has two
groups of values:

- ``sensor``: what the axis's sensors report (:data:`SENSOR_VALUES`, in the
  order of ``LeadScrewModel.joint_values()``), on ``joint_states`` and
  ``nut_position``; these may reach the graph late or not at all (sensor
  delay and dropped messages), stamped with their sampling time;
- ``truth``: the exact state of every body (:data:`TRUTH_VALUES`, in the
  order of ``LeadScrewModel.truth_values()``), on ``thread_force`` and
  ``sim/joint_states``, never delayed.

:data:`STATE_VALUES` says which values each state topic carries: a new
state topic is an entry in :data:`leadscrew_sim.io.topics.TOPIC_SPECS` and one
here. The value names are the columns of ``LeadScrewModel.run()`` (the
sensor ones with the prefix ``sensor_`` where a true value has the same name).
"""
from .cdr import (CdrReader, clock_template, CdrWriter, float64_template, joint_state_template,
                  Template, wrench_template)
from .record_fill import EncodedRows

#: What the sensors report in one tick: rad, m, rad/s, m/s, N m, N.
SENSOR_VALUES = ('screw_angle', 'nut_position', 'screw_velocity', 'nut_velocity',
                 'motor_torque', 'axial_force')

#: The ``model.run()`` column of each sensor value.
SENSOR_COLUMNS = ('sensor_screw_angle', 'sensor_nut_position', 'sensor_screw_velocity',
                  'sensor_nut_velocity', 'motor_torque', 'axial_force')

#: The exact state of one tick: rad, rad, m, m, rad/s, rad/s, m/s, m/s, N m, N m, N, N, N
#: (axial_force is the sum of nut_force and nut_b_force, as the kernel forms it).
TRUTH_VALUES = ('motor_angle', 'screw_angle', 'nut_position', 'nut_b_position',
                'motor_velocity', 'screw_velocity', 'nut_velocity', 'nut_b_velocity',
                'motor_torque', 'thread_torque', 'nut_force', 'nut_b_force', 'axial_force')

#: The thread contact and energy of one tick, the fields of ``sim/thread_state`` (type
#: leadscrew_sim/msg/ThreadState, recorded only).
THREAD_VALUES = ('contact_a', 'stick_a', 'normal_leading_a', 'normal_trailing_a',
                 'friction_a', 'sliding_velocity_a', 'contact_b', 'stick_b',
                 'normal_leading_b', 'normal_trailing_b', 'friction_b', 'sliding_velocity_b',
                 'input_work', 'external_work', 'kinetic', 'potential', 'spring',
                 'friction_dissipation', 'damping_dissipation')

#: The ageing of one tick, the fields of ``sim/ageing`` (type leadscrew_sim/msg/AgeingState;
#: m, m, m, N, -, -, -, degC, W, m).
AGEING_VALUES = ('wear_leading', 'wear_trailing', 'backlash', 'preload', 'lubricant', 'mu_k',
                 'mu_s', 'screw_temperature', 'heat_flow', 'thermal_growth')

#: The recorded-only values of one tick (``LeadScrewModel.analysis_values()``): the thread
#: state's, then the ageing's.
ANALYSIS_VALUES = THREAD_VALUES + AGEING_VALUES

#: The ``model.run()`` column of each analysis value.
ANALYSIS_COLUMNS = ('contact', 'stick_a', 'normal_leading', 'normal_trailing',
                    'friction_force', 'sliding_velocity', 'contact_b', 'stick_b',
                    'normal_leading_b', 'normal_trailing_b', 'friction_force_b',
                    'sliding_velocity_b', 'input_work', 'external_work', 'kinetic',
                    'potential', 'spring', 'friction_dissipation',
                    'damping_dissipation') + AGEING_VALUES

#: The joints of ``sim/joint_states`` (after the joint prefix); nut_b_joint only with a
#: split nut.
TRUTH_JOINTS = ('motor_joint', 'screw_joint', 'nut_joint', 'nut_b_joint')


def _truth_names(split_nut):
    n = 4 if split_nut else 3
    pos = ('motor_angle', 'screw_angle', 'nut_position', 'nut_b_position')[:n]
    vel = ('motor_velocity', 'screw_velocity', 'nut_velocity', 'nut_b_velocity')[:n]
    eff = ('motor_torque', 'thread_torque', 'nut_force', 'nut_b_force')[:n]
    return pos + vel + eff


#: State topic -> (stamped, group, the values its template takes, in order); the
#: values of sim/joint_states depend on the split nut (see StateEncoder).
STATE_VALUES = {
    'joint_states': (True, 'sensor', SENSOR_VALUES),
    'nut_position': (False, 'sensor', ('nut_position',)),
    'thread_force': (True, 'truth', ('axial_force', 'thread_torque')),
    'sim/joint_states': (True, 'truth', _truth_names(False)),
    'sim/thread_state': (True, 'analysis', THREAD_VALUES),
    'sim/ageing': (True, 'analysis', AGEING_VALUES),
}

#: The topics of each group.
SENSOR_TOPICS = tuple(t for t, (_s, g, _v) in STATE_VALUES.items() if g == 'sensor')
TRUTH_TOPICS = tuple(t for t, (_s, g, _v) in STATE_VALUES.items() if g == 'truth')
ANALYSIS_TOPICS = tuple(t for t, (_s, g, _v) in STATE_VALUES.items() if g == 'analysis')


def analysis_template(fields=THREAD_VALUES):
    """Template of a leadscrew_sim/msg/ThreadState (or of another type): header, float64 fields."""
    w = CdrWriter()
    stamp_off = w.stamp(0, 0)
    w.string('')
    return Template(w.buf, stamp_off, [w.f64(0.0) for _ in fields])


def decode_analysis(data, fields=THREAD_VALUES):
    """Return (stamp_ns, {name: value} of :data:`THREAD_VALUES`) of a sim/thread_state."""
    r = CdrReader(data)
    stamp = r.stamp()
    r.string()
    return stamp, {name: r.f64() for name in fields}


def decode_ageing(data):
    """Return (stamp_ns, {name: value} of :data:`AGEING_VALUES`) of a sim/ageing."""
    return decode_analysis(data, AGEING_VALUES)


class StateEncoder:
    """
    Encode the states of one tick, as the node publishes and records them.

    Joint names are ``<joint_prefix>screw_joint`` and ``<joint_prefix>nut_joint``
    on ``joint_states``; ``sim/joint_states`` names ``motor_joint``,
    ``screw_joint``, ``nut_joint`` and, with a split nut, ``nut_b_joint``. The
    templates are also attributes named as their topics (``sim/joint_states``
    as ``truth_joint_states``), each called as ``(stamp_ns, values)``;
    ``clock(stamp, ())`` encodes /clock. Stamps are integer nanoseconds >= 0.

    Parameters
    ----------
    joint_prefix : str
        Prefix of the joint names.
    split_nut : bool
        The axis has the anti-backlash half-nut B (a fourth joint on ``sim/joint_states``).

    """

    def __init__(self, joint_prefix='', split_nut=False):
        """Build the byte templates for the joint names of ``joint_prefix``."""
        self.joint_prefix = joint_prefix
        self.joint_names = (joint_prefix + 'screw_joint', joint_prefix + 'nut_joint')
        n = 4 if split_nut else 3
        self.truth_joints = tuple(joint_prefix + j for j in TRUTH_JOINTS[:n])
        self.templates = {
            'joint_states': joint_state_template(self.joint_names, 2, 2, 2),
            'nut_position': float64_template(),
            'thread_force': wrench_template(),
            'sim/joint_states': joint_state_template(self.truth_joints, n, n, n),
            'sim/thread_state': analysis_template(),
            'sim/ageing': analysis_template(AGEING_VALUES),
        }
        self.joint_states = self.templates['joint_states']
        self.nut_position = self.templates['nut_position']
        self.thread_force = self.templates['thread_force']
        self.truth_joint_states = self.templates['sim/joint_states']
        self.clock = clock_template()
        values = dict(STATE_VALUES)
        values['sim/joint_states'] = (True, 'truth', _truth_names(split_nut))
        order = {'sensor': SENSOR_VALUES, 'truth': TRUTH_VALUES, 'analysis': ANALYSIS_VALUES}
        self._plan = {
            group: tuple((topic, self.templates[topic], stamped,
                          tuple(order[group].index(name) for name in names), names)
                         for topic, (stamped, g, names) in values.items() if g == group)
            for group in order}

    def encode(self, group, stamp_ns, values):
        """
        Return [(topic, bytes)] of the topics of a group for one tick.

        Parameters
        ----------
        group : str
            ``'sensor'`` (values of :data:`SENSOR_VALUES`; stamp: the sampling
            time), ``'truth'`` (:data:`TRUTH_VALUES`) or ``'analysis'``
            (:data:`ANALYSIS_VALUES`, the recorded-only topic).
        stamp_ns : int
            The stamp [ns].
        values : sequence of float
            The group's values, in the order of its tuple.

        """
        return [(topic, template(stamp_ns if stamped else None, [values[i] for i in index]))
                for topic, template, stamped, index, _n in self._plan[group]]

    def sensor(self, stamp_ns, values):
        """Return :meth:`encode` of the sensor topics of one sample (stamp: its sampling time)."""
        return self.encode('sensor', stamp_ns, values)

    def truth(self, stamp_ns, values):
        """Return :meth:`encode` of the truth topics of one tick."""
        return self.encode('truth', stamp_ns, values)

    def analysis(self, stamp_ns, values):
        """Return :meth:`encode` of the recorded-only analysis topic of one tick."""
        return self.encode('analysis', stamp_ns, values)

    def rows(self, group, stamps_ns, columns):
        """
        Return [(topic, uint8 rows)] of the topics of a group for many ticks at once.

        Parameters
        ----------
        group : str
            ``'sensor'`` or ``'truth'``.
        stamps_ns : numpy.ndarray of int64
            Stamp of each row [ns].
        columns : mapping of str to numpy.ndarray
            One array per value name of the group.

        """
        return [(topic, template.rows(stamps_ns if stamped else None,
                                      [columns[name] for name in names]))
                for topic, template, stamped, _i, names in self._plan[group]]

    def encoded(self, group, stamps_ns, columns):
        """
        Return [(topic, EncodedRows)]: :meth:`rows`, encoded only when written.

        Parameters
        ----------
        group : str
            ``'sensor'``, ``'truth'`` or ``'analysis'``.
        stamps_ns : numpy.ndarray of int64
            Stamp of each row [ns].
        columns : mapping of str to numpy.ndarray
            One array per value name of the group.

        """
        return [(topic, EncodedRows.of_template(template, stamps_ns,
                                                [columns[name] for name in names]))
                for topic, template, stamped, _i, names in self._plan[group]]
