"""
The node's tick: one fixed step of the model and what it publishes, a mix-in of the node class.

Each step takes the held command, advances the model by dt and publishes
(and records) the states stamped ``t0 + n dt`` [ns]: the sensor samples through
:class:`~leadscrew_sim.core.delivery.StateDelivery` (delay, loss), the truth
on every ``publish_decimation``-th step, the switches on a change and at
10 Hz, /clock in the sim-time modes; a new drive fault is logged. Once a
second the loops publish the diagnostics (:meth:`Stepping._publish_diagnostics`).
"""
from rclpy.serialization import serialize_message

from ..core.drive_modes import FAULT_NAMES
from ..core.faults import SimulationFault
from ..io.cdr import encode_bool
from ..io.topics import SWITCH_TOPICS
from .diagnostics import diagnostic_array

NS = 1_000_000_000


class Stepping:
    """The step, the publishers and the diagnostics (a mix-in: uses the node's state)."""

    def _step(self, age_now):
        """Advance one fixed step and publish; age_now is the time base of command ages."""
        model = self.model
        if model.fault:
            if self.mode == 'realtime':     # the stamps stay on the clock; nothing to publish
                self.n += 1
            return
        command = self.inputs.command_for_step(age_now)
        if command is not None:
            model.command(*command)
        try:
            model.advance_held(self.inputs.hold.force)
        except SimulationFault as exc:
            self.get_logger().error(f'simulation fault, integration stopped: {exc}; '
                                    'call ~/reset to restart')
            return
        self.n += 1
        if self.params.max_command_jump > 0.0:
            self._watch_far_commands(command)
        self._publish_states(self.n % self.settings.publish_decimation == 0)
        switches = model.switches()
        if switches != self._switches or self.n % self._switch_period == 0:
            self._publish_switches(switches)       # on a change and at 10 Hz
        fault = model.drive_fault()
        if fault != self._fault_seen:
            self._log_fault(fault)
        if self._pub_clock is not None:
            self._emit('/clock', self._ser_clock(self._sim_now(), ()))

    def _watch_far_commands(self, command):
        """Count and log a position command the drive approaches instead of taking at once."""
        gap = self.model.reference_gap()
        if gap != 0.0 and command is not None and self._reference_gap == 0.0:
            self.far_commands += 1
            metres = abs(gap) * self.params.lead_ratio
            self.get_logger().warn(
                f'position command {metres:.6g} m from the drive reference, beyond '
                f'max_command_jump {self.params.max_command_jump:g} m: approached at the '
                f"drive's limits ({self.far_commands} such commands so far)",
                throttle_duration_sec=1.0)
        self._reference_gap = gap

    def _publish_states(self, sampled):
        """
        Publish the sensor samples due now and, on a sampled tick, the truth.

        The sensor states pass through :class:`StateDelivery` (delay, loss) with
        their sampling stamp; /tf follows the last delivered joint values.
        """
        stamp, model, enc = self._sim_now(), self.model, self._encoder
        delivery = self.delivery
        if sampled:
            delivery.sample(self.n, stamp, model.joint_values())
        values = None
        for s_stamp, values in delivery.due(self.n):
            for topic, data in enc.sensor(s_stamp, values):
                self._emit(topic, data)
        if sampled:
            for topic, data in enc.truth(stamp, model.truth_values()):
                self._emit(topic, data)
            if self.sink.active:
                for topic, data in enc.analysis(stamp, model.analysis_values()):
                    self.sink.write(self._rec_topic[topic], data, stamp)
            self._publish_ageing()
        if values is not None and self._desc is not None:
            self._desc.publish_tf(s_stamp, values[0], values[1], self.sink, self._publishing)

    def _publish_switches(self, switches):
        """Publish and record the switch states (on a change and at 10 Hz)."""
        self._switches = switches
        for topic, on in zip(SWITCH_TOPICS, switches):
            self._emit(topic, encode_bool(on == 1.0))

    def _log_fault(self, code):
        self._fault_seen = code
        if code:
            st = self.model.drive_status()
            if self.model.is_stepper:
                self.get_logger().error(f'drive fault: {FAULT_NAMES[code]}; stepper disabled, '
                                        'windings open until ~/clear_fault')
                return
            self.get_logger().error(
                f'drive fault: {FAULT_NAMES[code]} (following error '
                f'{st["following_error"]:.6g} rad); torque off until ~/clear_fault')

    def _emit(self, topic, data):
        """Publish the serialized state ``data`` on ``topic`` (unless silent) and record it."""
        if self._publishing:
            self._pubs[topic].publish(data)
        if self.sink.active:
            self.sink.write(self._rec_topic[topic], data, self._sim_now())

    def _lockstep_tick(self):
        self.tick_time = self._sim_now()
        self._step(self.tick_time)
        self.loop.steps(1)
        self.recorder.flush()

    def _publish_diagnostics(self, now):
        lateness = self.loop.window(now)
        self._next_diag = now + NS
        self.recorder.poll()
        inp = self.inputs
        age = inp.age(now, None if self.mode == 'realtime' else self._sim_now())
        arr = diagnostic_array(
            name=self.get_name(), preset=self.preset, params=self.params, model=self.model,
            clock_mode=self.mode, sim_time_ns=self._sim_now(),
            target_rate=self.settings.update_rate, command_age=age, stale=inp.hold.stale,
            loop=self.loop, lateness=lateness,
            counts=(inp.commands, inp.rejected, inp.ignored), recorder=self.recorder,
            dropped=(inp.hold.dropped, self.delivery.dropped),
            live=None if self._live is None else self._live.status(),
            far_commands=self.far_commands)
        data = serialize_message(arr)
        self._pub_diag.publish(data)
        if self.sink.active:
            self.sink.write(self._rec_topic['diagnostics'], data, self._sim_now())
