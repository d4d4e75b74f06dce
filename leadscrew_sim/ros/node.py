"""
ROS 2 node ``leadscrew_sim_node``: the lead screw axis on the ROS graph.

Interfaces: doc/interfaces.md. Commands (``torque_command``,
``joint_commands``, ``external_force``) are zero-order held; every tick the
model advances by exactly one fixed step ``dt = 1 / update_rate`` and the
states (``joint_states``, ``nut_position``, ``thread_force``) are published
with the stamp ``t0 + n dt`` (integer nanoseconds, strictly increasing).

Clock modes (read-only parameter ``clock_mode``):

- ``realtime``: absolute-deadline loop on CLOCK_MONOTONIC; t0 is the system
  (ROS) time at construction, paired with a monotonic instant, and step n is
  due at t0 + n dt, so every stamp is the system time of its tick. A late
  tick takes every step due; beyond ``max_catchup_steps`` extra steps (a
  stall) the older ones are integrated and recorded but not published, and
  counted in the diagnostics' skipped_steps.
- ``stepped``: sim time from 0, ``/clock`` every tick, as fast as possible
  (``real_time_factor`` 0) or paced at ``real_time_factor``.
- ``lockstep``: one tick per received ``torque_command`` or ``joint_commands``
  message, sim time from 0, ``/clock`` every tick.

A command recorded in the MCAP file carries the log time ``t0 + n dt`` where
n is the number of steps taken before it; it first acts on the step from
``t0 + n dt`` to ``t0 + (n + 1) dt`` (the state stamped ``t0 + (n + 1) dt``).

This module is the adapter between the graph and the core: commands go
through :mod:`.commands` into a :class:`~leadscrew_sim.core.commands.CommandHold`,
each tick steps the model and hands the encoded states to the publishers and
the recorder (:mod:`leadscrew_sim.io.recorder`). Topics and QoS come from
:data:`leadscrew_sim.io.topics.TOPIC_SPECS`; parameters: :mod:`.parameters`;
diagnostics: :mod:`.diagnostics`; deadline timing: :mod:`.timing`; the
mix-ins of the node class: the main loops (:mod:`.loops`), the command
callbacks (:mod:`.command_callbacks`), each tick's step and what it
publishes (:mod:`.stepping`) and the services (:mod:`.services`). With
``foxglove_port`` the messages also go to the live view (:mod:`.foxglove_live`,
imported only then): ``self.sink`` is where every message's bytes go.
"""
import json
import math
import os
import signal
import sys

from diagnostic_msgs.msg import DiagnosticArray
from rcl_interfaces.msg import SetParametersResult
import rclpy
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from std_srvs.srv import SetBool, Trigger

from ..core import ParameterError, ScrewParams
from ..core.commands import COMMAND_LOG_TIME, NutMap
from ..core.delivery import StateDelivery
from ..core.model import LeadScrewModel, MAX_SUBSTEPS_PER_STEP
from ..core.warmup import kernel_ready
from ..io.messages import StateEncoder
from ..io.recorder import Recorder
from ..io.run_file import UPDATE_RECORD
from ..io.session import StorageOptions
from ..io.topics import graph_name, TOPIC_SPECS
from .ageing import AxisAgeing
from .command_callbacks import CommandCallbacks
from .commands import CommandInputs
from .description import RobotDescription
from .interfaces import message_class, qos_profile
from .loops import ClockLoops
from .services import AxisServices
from .stepping import Stepping
from .parameters import (declare_live_view, DEFAULT_PRESET, declare_parameters,
                         integers_as_doubles, StartupError, validate_changes)
from .timing import clock_pair, LoopStats

__all__ = ['COMMAND_QOS', 'DEFAULT_PRESET', 'LeadScrewSimNode', 'main', 'make_executor',
           'NODE_NAME', 'qos_profile', 'STATE_QOS', 'StartupError']

NODE_NAME = 'leadscrew_sim_node'
NS = 1_000_000_000


COMMAND_QOS = qos_profile(TOPIC_SPECS['torque_command'][2])
STATE_QOS = qos_profile(TOPIC_SPECS['joint_states'][2])


class LeadScrewSimNode(AxisAgeing, AxisServices, ClockLoops, CommandCallbacks, Stepping, Node):
    """The simulated lead screw axis (see the module docstring)."""

    def __init__(self, **kwargs):
        """
        Declare and validate the parameters, build the model and the ROS interfaces.

        A start-up that fails (bad parameters, a taken port) destroys the node before it
        raises: its DDS participant is released while rclpy is still up, not by the garbage
        collector at interpreter exit, where a live participant can hang the process.
        """
        super().__init__(NODE_NAME, **kwargs)
        try:
            self._start()
        except BaseException:
            if getattr(self, 'recorder', None) is not None:
                self.recorder.stop()
            if getattr(self, '_live', None) is not None:
                self._live.stop()
            self.destroy_node()
            raise

    def _start(self):
        """Build what __init__ promises: parameters, model, interfaces, ageing, recording."""
        self._running = True
        self.preset, self.params, self.settings = declare_parameters(self)
        s = self.settings
        self.dt_ns = int(round(NS / s.update_rate))
        self._spin_budget_ns = max(100_000, self.dt_ns // 4)
        self.model = self._make_model()
        kernel_ready(self.get_logger().info, self.params)   # every entry point, logged
        self.mode = s.clock_mode
        # realtime: t0 is the system time (ROS time) of the monotonic instant t0_mono the
        # loop's deadlines count from, so the stamp t0 + n dt is the system time of tick n
        self.t0_ns, self.t0_mono_ns = clock_pair() if self.mode == 'realtime' else (0, 0)
        self.n = 0                         # steps taken; stamp = t0 + n dt
        self._publishing = True            # False while a stall's old steps are integrated
        self.far_commands = 0              # position commands beyond max_command_jump
        self._reference_gap = 0.0          # the drive's reference_gap after the last step

        # Commands (zero-order held, in the time base of _command_time) and counters.
        self.inputs = CommandInputs(self.get_logger(), s.joint_prefix, s.command_timeout,
                                    NutMap.of_model(self.model), s.joint_command_mode,
                                    self.params)
        self.delivery = StateDelivery(self.params)   # the sensor states' delay and loss
        self.tick_time = 0                 # time base of command ages (see _step)
        self._events = 0

        self.loop = LoopStats(keep_all=bool(s.stats_file))
        self.recorder = Recorder(self.get_logger())
        self.sink = self.recorder           # where the messages go (see _start_live_view)
        self._live = None
        live_host, live_port = declare_live_view(self)
        self._build_interfaces()
        self._start_ageing()
        self._build_description()
        if live_port:
            self._start_live_view(live_host, live_port)
        self.add_pre_set_parameters_callback(integers_as_doubles)
        self.add_on_set_parameters_callback(self._on_set_parameters)
        p = self.params
        self.get_logger().info(
            f'preset {self.preset}: {p.thread_form} d={p.major_diameter * 1e3:g} mm '
            f'lead {p.lead * 1e3:g} mm {p.hand}-hand, '
            f'{"self-locking" if p.self_locking else "back-drivable"}; '
            f'{s.update_rate:g} Hz, {self.model.nsub} substeps/step, '
            f'clock_mode {self.mode}')
        if self.model.is_stepper:
            self.get_logger().info(
                f'stepper drive: {p.holding_torque:g} N m at {p.run_current:g} A, '
                f'{p.microsteps} microsteps, {p.supply_voltage:g} V; position and velocity '
                'commands only (torque commands are refused); joint_states reports '
                + ('the motor encoder' if p.encoder_counts > 0 else 'the commanded steps'))
        for note in p.advisories():
            self.get_logger().warn(note)
        if s.record:
            self._start_recording()

    def _make_model(self):
        """Build the model; a set needing too many substeps per step is a StartupError."""
        dt = self.dt_ns / NS
        try:
            return LeadScrewModel(self.params, dt=dt)
        except ParameterError as exc:
            p = self.params
            if p.substep > 0.0 and dt / p.substep > MAX_SUBSTEPS_PER_STEP:
                raise StartupError(
                    f"parameter 'substep': {p.substep:g} s gives "
                    f'{math.ceil(dt / p.substep)} substeps per {dt:g} s step (limit '
                    f'{MAX_SUBSTEPS_PER_STEP}); raise it (0: automatic) or update_rate'
                ) from None
            raise StartupError(f'{exc} (update_rate {self.settings.update_rate:g} Hz)') from None

    # -- parameters --------------------------------------------------------
    def all_parameter_values(self):
        """Return {name: str(value)} of every parameter plus the run settings."""
        values = {public: str(getattr(self.params, name)) for name, public in
                  zip(ScrewParams.names(), ScrewParams.parameter_names())}
        values.update({name: str(v) for name, v in self.settings.to_dict().items()})
        values.update(preset=self.preset, update_rate=str(self.settings.update_rate),
                      clock_mode=self.mode, dt_ns=str(self.dt_ns), t0_ns=str(self.t0_ns),
                      command_log_time=COMMAND_LOG_TIME)
        return values

    def _on_set_parameters(self, parameters):
        try:
            change = validate_changes(parameters, self.params, self.settings)
            if change.params is not None:
                self.model.set_params(change.params)
        except ParameterError as exc:
            return SetParametersResult(successful=False, reason=str(exc))
        if change.params is not None:
            for note in set(change.params.advisories()) - set(self.params.advisories()):
                self.get_logger().warn(note)
            self.params = change.params
            self.inputs.hold.set_faults(change.params)
            self.delivery.set_faults(change.params)
            self.recorder.add_metadata(UPDATE_RECORD, dict(
                {k: str(v) for k, v in change.physics.items()},
                log_time_ns=str(self._sim_now())))
        if change.settings is not None:
            self._apply_settings(change.run, change.settings)
            self.recorder.add_metadata(UPDATE_RECORD, dict(
                {k: str(getattr(change.settings, k)) for k in change.run},
                log_time_ns=str(self._sim_now())))
        if self._live is not None:
            self._live.parameters_set(parameters)
        return SetParametersResult(successful=True)

    def _apply_settings(self, names, new):
        """Take the new run settings; ``names`` are the ones set (changed or not)."""
        old, self.settings = self.settings, new
        self.inputs.set_timeout(new.command_timeout)
        self.inputs.set_joint_command_mode(new.joint_command_mode)
        if new.joint_prefix != old.joint_prefix:
            self.inputs.set_joint_prefix(new.joint_prefix)
            self._make_serializers()
        if 'real_time_factor' in names:
            self._pace_reset = True
        if new.record != old.record:
            if new.record:
                self._start_recording()
            else:
                self._note_ageing_end()
                self.recorder.stop(wait=False)
                self.get_logger().info('recording stopped')

    # -- ROS interfaces ------------------------------------------------------
    def _build_interfaces(self):
        """Create the publishers and subscriptions of the topic table, and the services."""
        callbacks = self.command_callbacks()
        self._pubs, self._rec_topic = {}, {}
        for topic, (type_name, role, qos) in TOPIC_SPECS.items():
            if role in ('record', 'diagnostics'):   # recorded only; diagnostics: see below
                if role == 'record':
                    self._rec_topic[topic] = self.resolve_topic_name(topic)
                continue
            msg_type, profile = message_class(type_name), qos_profile(qos)
            name = graph_name(topic)
            if role == 'command':
                ent = self.create_subscription(msg_type, name, callbacks[topic], profile,
                                               raw=True)
            elif role in ('state', 'switch') or self.mode != 'realtime':   # /clock: sim time
                ent = self._pubs[topic] = self.create_publisher(msg_type, name, profile)
            else:
                continue
            self._rec_topic[topic] = ent.topic_name
        self._pub_clock = self._pubs.get('/clock')
        self._pub_diag = self.create_publisher(DiagnosticArray, 'diagnostics', 10)
        self._rec_topic['diagnostics'] = self._pub_diag.topic_name
        self.create_service(Trigger, '~/reset', self._on_reset)
        self.create_service(Trigger, '~/clear_fault', self._on_clear_fault)
        self._switches = None               # last published (min, max, home)
        self._switch_period = max(1, round(self.settings.update_rate / 10.0))   # steps
        self._fault_seen = 0                # drive fault code already logged
        self.create_service(SetBool, '~/record', self._on_record)
        self._make_serializers()
        self._pace_reset = True

    def _build_description(self):
        """Render the URDF (its channels are recorded); publish it with publish_tf."""
        self._desc = RobotDescription.make(self, self.params, self.settings.joint_prefix,
                                           self.settings.publish_tf)
        if self._desc is not None:
            self._rec_topic.update(self._desc.topics)
            self._desc.publish_static(self._sim_now(), None)

    def _start_live_view(self, host, port):
        """Serve Foxglove on host:port (StartupError if the port is taken)."""
        from .foxglove_live import LiveView     # the SDK is imported only with a port
        self._live = LiveView(self, host, port)
        self.sink = self._live.sink(self.recorder)
        if self.mode == 'lockstep':                 # its loop only waits for commands
            self.create_timer(0.01, self._live.drain)
        else:
            self._spin = self._drain_and_spin

    def _drain_and_spin(self):
        """Take the live view's commands and parameter requests, then the tick's ROS events."""
        self._live.drain()
        ClockLoops._spin(self)

    def _make_serializers(self):
        self._encoder = StateEncoder(self.settings.joint_prefix, self.params.anti_backlash)
        self._ser_clock = self._encoder.clock

    def recording_channels(self):
        """
        Return {resolved topic: (type name, offered QoS yaml, trim)} of the recorded topics.

        ``trim``: the recorder cuts bytes past the CDR end (commands as received);
        the states are our exact encodings and need no check. The QoS is the
        recorder's default (reliable, keep last 10).
        """
        chans = {self._rec_topic[topic]: (type_name, None, role == 'command')
                 for topic, (type_name, role, _qos) in TOPIC_SPECS.items()
                 if topic in self._rec_topic}
        if self._desc is not None:
            chans.update(self._desc.channels())
        return chans

    def _start_recording(self):
        """Start a recording; log and return the file it writes (None if it failed)."""
        if not self.recorder.start(StorageOptions.from_run_settings(self.settings),
                                   self.recording_channels(),
                                   dict(self.all_parameter_values(), **self.ageing_metadata())):
            return None
        if self._desc is not None:
            self._desc.publish_static(self._sim_now(), self.recorder)
        path = self.recorder.wait_for_path(timeout=5.0)
        if path:
            self.get_logger().info(f'recording to {os.path.abspath(path)}')
        return path

    # -- sim time ----------------------------------------------------------------
    def _sim_now(self):
        return self.t0_ns + self.n * self.dt_ns

    # -- statistics and shutdown --------------------------------------------------
    def timing_stats(self):
        """Return the timing statistics of the run so far (lateness in ns)."""
        return dict(
            clock_mode=self.mode, update_rate=self.settings.update_rate, steps=self.n,
            **self.loop.run_stats(),
            rejected_commands=self.inputs.rejected, ignored_commands=self.inputs.ignored,
            commands=self.inputs.commands, fault=self.model.fault)

    def close(self):
        """Write the stats file, close the recorder."""
        path = self.settings.stats_file
        if path and self.loop.run_start:
            try:
                with open(path, 'w') as fh:
                    json.dump(self.timing_stats(), fh, indent=1)
            except OSError as exc:
                self.get_logger().error(f'cannot write stats_file {path!r}: {exc}')
        self._save_ageing()
        self._note_ageing_end()
        self.recorder.stop()
        if self._live is not None:
            self._live.stop()


def make_executor(context=None):
    """Return an EventsExecutor, or a SingleThreadedExecutor if it is unavailable."""
    try:
        from rclpy.experimental import EventsExecutor
        return EventsExecutor(context=context)
    except (ImportError, AttributeError, RuntimeError):
        return SingleThreadedExecutor(context=context)


def main(args=None):
    """Run the node until SIGINT/SIGTERM; return the exit code (2: bad parameters)."""
    from rclpy.signals import SignalHandlerOptions
    argv = sys.argv if args is None else args
    try:
        rclpy.init(args=argv, signal_handler_options=SignalHandlerOptions.NO)
    except Exception as exc:  # noqa: B902 - bad --ros-args
        print(f'{NODE_NAME}: error: {exc}', file=sys.stderr)
        return 2
    node = None
    stop_early = []

    def on_signal(_signum, _frame):
        if node is not None:
            node.stop()
        stop_early.append(True)

    # Before the node exists: a Ctrl-C during start-up (numba, DDS discovery
    # can take seconds) ends the node cleanly instead of with a traceback.
    signal.signal(signal.SIGINT, on_signal)
    signal.signal(signal.SIGTERM, on_signal)
    try:
        try:
            node = LeadScrewSimNode()
        except StartupError as exc:
            print(f'{NODE_NAME}: error: {exc}', file=sys.stderr, flush=True)
            return 2
        except (rclpy.exceptions.InvalidParameterValueException,
                rclpy.exceptions.InvalidParameterTypeException,
                rclpy.exceptions.ParameterException) as exc:
            print(f'{NODE_NAME}: error: {exc}', file=sys.stderr, flush=True)
            return 2
        if stop_early:
            node.stop()
        executor = make_executor()
        executor.add_node(node)
        node.run(executor)
        node.close()
        node.get_logger().info(f'stopped after {node.n} steps')
        return 0
    finally:
        # A launch file forwards Ctrl-C to its nodes after the terminal did: a
        # second SIGINT during teardown must not end the process with -2.
        signal.signal(signal.SIGINT, signal.SIG_IGN)
        signal.signal(signal.SIGTERM, signal.SIG_IGN)
        if node is not None:
            node.destroy_node()
        if rclpy.ok():
            rclpy.shutdown()


if __name__ == '__main__':
    sys.exit(main())
