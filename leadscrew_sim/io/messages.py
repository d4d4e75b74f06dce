"""
The state messages of one tick, encoded as the node publishes and records them.

The node, ``simulate`` and ``resim`` all encode their states through
:class:`StateEncoder`, so their files hold the same bytes.
"""
from .cdr import clock_template, float64_template, joint_state_template, wrench_template


class StateEncoder:
    """
    Encode the states of one tick, as the node publishes and records them.

    Joint names are ``<joint_prefix>screw_joint`` and ``<joint_prefix>nut_joint``.
    Each method takes ``(stamp_ns, values)`` like the node's serializers:

    - ``joint_states(stamp, (screw_angle, nut_position, screw_velocity,
      nut_velocity, motor_torque, axial_force))``;
    - ``nut_position(stamp_or_None, (x,))``;
    - ``thread_force(stamp, (axial_force, thread_torque))``;
    - ``clock(stamp, ())``.

    Stamps are integer nanoseconds >= 0 (sec fits int32).
    """

    def __init__(self, joint_prefix=''):
        """Build the byte templates for the joint names of ``joint_prefix``."""
        self.joint_prefix = joint_prefix
        self.joint_names = (joint_prefix + 'screw_joint', joint_prefix + 'nut_joint')
        self.joint_states = joint_state_template(self.joint_names, 2, 2, 2)
        self.nut_position = float64_template()
        self.thread_force = wrench_template()
        self.clock = clock_template()

    @staticmethod
    def values(o):
        """Return the value tuples (joint_states, nut_position, thread_force) of a StepOutput."""
        return ((o.screw_angle, o.nut_position, o.screw_velocity, o.nut_velocity,
                 o.motor_torque, o.axial_force), (o.nut_position,),
                (o.axial_force, o.thread_torque))

    def encode(self, stamp_ns, o):
        """Return the bytes of (joint_states, nut_position, thread_force) for a StepOutput."""
        js, x, wr = self.values(o)
        return (self.joint_states(stamp_ns, js), self.nut_position(None, x),
                self.thread_force(stamp_ns, wr))
