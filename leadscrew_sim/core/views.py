"""
The per-tick values a model reports, as plain floats: a mix-in of :class:`.model.LeadScrewModel`.

The node's fast path: what the sensors report (:meth:`ReportedValues.joint_values`),
the truth of every body (:meth:`~ReportedValues.truth_values`) and the thread contact
and energy terms (:meth:`~ReportedValues.analysis_values`), read from the model's
state and outputs without building a StepOutput. Angles and torques in the theta sense.
"""
from .engine import layout as L


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
        o, hs = self.out.tolist(), self.params.hand_sign
        return (hs * o[L.O_JQ], o[L.O_JX], hs * o[L.O_JW], o[L.O_JV], hs * o[L.O_TE] + 0.0,
                o[L.O_FAX])

    def truth_values(self):
        """
        Return the exact state of every body as a tuple of floats (``sim/joint_states``).

        (motor angle [rad], screw angle [rad], nut A position [m], half-nut B
        position [m], motor rate [rad/s], screw rate [rad/s], nut A velocity
        [m/s], half-nut B velocity [m/s], applied motor torque [N m], thread
        torque on the screw [N m], axial thread force on nut A [N], on half-nut
        B [N], on both [N]); without a split nut B follows A and carries no force.
        """
        s, o, hs = self.state.tolist(), self.out.tolist(), self.params.hand_sign
        cl, sl = float(self._P[L.P_CL]), float(self._P[L.P_SL])
        f_a = (o[L.O_NLA] - o[L.O_NUA]) * cl + o[L.O_FFA] * sl
        return (hs * s[L.S_QM], hs * s[L.S_Q], s[L.S_XA], s[L.S_XB], hs * s[L.S_WM],
                hs * s[L.S_DQ], s[L.S_VA], s[L.S_VB], hs * o[L.O_TE] + 0.0, hs * o[L.O_TTH],
                f_a, o[L.O_FAX] - f_a, o[L.O_FAX])

    def analysis_values(self):
        """
        Return the thread contact of both nut bodies and the energy terms, as floats.

        (contact, stick, leading and trailing flank normal force [N], friction
        force [N] and sliding velocity [m/s] of nut A, the same six of half-nut
        B, then input_work, external_work, kinetic, potential, spring,
        friction_dissipation, damping_dissipation [J] of :meth:`energy`):
        contact 1 leading flank, -1 trailing, 0 in the backlash; stick 1 stuck,
        0 sliding, -1 no load.
        """
        o = self.out.tolist()
        e = self.energy()
        return (o[L.O_CONTA], o[L.O_STICKA], o[L.O_NLA], o[L.O_NUA], o[L.O_FFA], o[L.O_VSA],
                o[L.O_CONTB], o[L.O_STICKB], o[L.O_NLB], o[L.O_NUB], o[L.O_FFB], o[L.O_VSB],
                *(float(e[k]) for k in ('input_work', 'external_work', 'kinetic', 'potential',
                                        'spring', 'friction_dissipation',
                                        'damping_dissipation')))
