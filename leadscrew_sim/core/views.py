"""
The per-tick values a model reports, as plain floats: a mix-in of :class:`.model.LeadScrewModel`.

The node's fast path: what the sensors report (:meth:`ReportedValues.joint_values`),
the truth of every body (:meth:`~ReportedValues.truth_values`) and the thread contact
and energy terms (:meth:`~ReportedValues.analysis_values`), read from the model's
state and outputs without building a StepOutput. Angles and torques in the theta sense,
by the rule of :data:`.output.REPORTED`.
"""
from .engine import layout as L
from .output import nut_forces, Reading, record_row

_JOINT = Reading(('sensor_screw_angle', 'sensor_nut_position', 'sensor_screw_velocity',
                  'sensor_nut_velocity', 'motor_torque', 'axial_force'))
_TRUTH = Reading(('motor_angle', 'screw_angle', 'nut_position', 'nut_b_position',
                  'motor_velocity', 'screw_velocity', 'nut_velocity', 'nut_b_velocity',
                  'motor_torque', 'thread_torque', 'normal_leading', 'normal_trailing',
                  'friction_force', 'axial_force'))
_ANALYSIS = Reading(('contact', 'stick_a', 'normal_leading', 'normal_trailing', 'friction_force',
                     'sliding_velocity', 'contact_b', 'stick_b', 'normal_leading_b',
                     'normal_trailing_b', 'friction_force_b', 'sliding_velocity_b'))
_ENERGY = ('input_work', 'external_work', 'kinetic', 'potential', 'spring',
           'friction_dissipation', 'damping_dissipation')
_AGEING = Reading(('wear_leading_a', 'wear_leading_b', 'wear_trailing_a', 'wear_trailing_b',
                   'backlash', 'preload', 'lubricant', 'mu_k', 'mu_s', 'screw_temperature',
                   'heat_flow', 'thermal_growth'))


class ReportedValues:
    """The tuples of floats a tick publishes and records (uses the model's state and outputs)."""

    def joint_values(self):
        """
        Return what the sensors report as a tuple of floats (the node's per-tick fast path).

        (screw_angle [rad], nut_position [m], screw_velocity [rad/s],
        nut_velocity [m/s], motor_torque [N m], axial_force [N]): the screw
        joint from the motor encoder, the nut joint from the linear scale (or
        the encoder through the lead without one), the applied motor torque and
        the axial thread force. With ideal sensors these are the true values of
        :meth:`output`.
        """
        return tuple(_JOINT(record_row(self.state, self.out), self.params.hand_sign))

    def truth_values(self):
        """
        Return the exact state of every body as a tuple of floats (``sim/joint_states``).

        (motor angle [rad], screw angle [rad], nut A position [m], half-nut B
        position [m], motor rate [rad/s], screw rate [rad/s], nut A velocity
        [m/s], half-nut B velocity [m/s], applied motor torque [N m], thread
        torque on the screw [N m], axial thread force on nut A [N], on half-nut
        B [N], on both [N]); without a split nut B follows A and carries no force.
        """
        v = _TRUTH(record_row(self.state, self.out), self.params.hand_sign)
        f_a, f_b = nut_forces(*v[10:], float(self._P[L.P_CL]), float(self._P[L.P_SL]))
        return (*v[:10], f_a, f_b, v[13])

    def analysis_values(self):
        """
        Return the thread contact of both nut bodies and the energy terms, as floats.

        (contact, stick, leading and trailing flank normal force [N], friction
        force [N] and sliding velocity [m/s] of nut A, the same six of half-nut
        B, then input_work, external_work, kinetic, potential, spring,
        friction_dissipation, damping_dissipation [J] of :meth:`energy`):
        contact 1 leading flank, -1 trailing, 0 in the backlash; stick 1 stuck,
        0 sliding, -1 no load. Then the ageing of :meth:`ageing_values`.
        """
        e = self.energy()
        row = record_row(self.state, self.out)
        v = _ANALYSIS(row, self.params.hand_sign)
        return (*v, *(float(e[k]) for k in _ENERGY), *self._ageing_of(row))

    def ageing_values(self):
        """
        Return the ageing of the axis as floats: the fields of a ``sim/ageing`` message.

        (wear_leading, wear_trailing [m] summed over the nut bodies, the
        effective backlash [m], the preload [N], lubricant [-], mu_k, mu_s
        [-], screw_temperature [degC], heat_flow into the screw [W],
        thermal_growth at the nut [m]): :data:`.ageing.REPORTED_FIELDS`.
        """
        return self._ageing_of(record_row(self.state, self.out))

    def _ageing_of(self, row):
        v = _AGEING(row, 1.0)
        return (v[0] + v[1], v[2] + v[3], *v[4:])
