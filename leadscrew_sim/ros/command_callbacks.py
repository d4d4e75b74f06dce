"""
The node's command subscriptions: record each message, hold it, step in lockstep.

A mix-in of the node class. Each callback takes the raw CDR bytes of one
command (``torque_command`` [N m], ``joint_commands``, ``velocity_command``
[m/s], ``position_command`` [m], ``external_force`` [N]), records it at the
current sim time, hands it to :class:`.commands.CommandInputs` in the time
base of command ages and, in ``lockstep``, takes the tick it triggers. The
live view's commands come through the same callbacks.
"""


class CommandCallbacks:
    """The command callbacks (a mix-in: uses the node's inputs, sink and clock)."""

    def command_callbacks(self):
        """Return {command topic: callback taking the CDR bytes} (ROS and the live view)."""
        return {'torque_command': self._on_torque,
                'joint_commands': self._on_joint_commands,
                'external_force': self._on_force,
                'velocity_command': self._on_velocity,
                'position_command': self._on_position}

    def _command_time(self):
        # lockstep: the command arrives before its tick, at the current sim time
        return self._sim_now() if self.mode == 'lockstep' else self.tick_time

    def _record_cmd(self, topic, data):
        self._events += 1
        if self.sink.active:
            self.sink.write(self._rec_topic[topic], data, self._sim_now())

    def _on_torque(self, data):
        self._record_cmd('torque_command', data)
        self.inputs.torque_command(data, self._command_time())
        if self.mode == 'lockstep':
            self._lockstep_tick()

    def _on_joint_commands(self, data):
        self._record_cmd('joint_commands', data)
        self.inputs.joint_commands(data, self._command_time())
        if self.mode == 'lockstep':
            self._lockstep_tick()

    def _on_velocity(self, data):
        self._record_cmd('velocity_command', data)
        self.inputs.velocity_command(data, self._command_time())
        if self.mode == 'lockstep':
            self._lockstep_tick()

    def _on_position(self, data):
        self._record_cmd('position_command', data)
        self.inputs.position_command(data, self._command_time())
        if self.mode == 'lockstep':
            self._lockstep_tick()

    def _on_force(self, data):
        self._record_cmd('external_force', data)
        self.inputs.external_force(data)
