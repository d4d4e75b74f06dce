"""
The node's live view in Foxglove (parameter ``foxglove_port``): the node's side of the server.

The server (:class:`leadscrew_sim.io.foxglove_server.LiveServer`) serves
every channel the node records, with the bytes it publishes and records.
What a client sends reaches the node on its own thread: the SDK's callbacks
only queue commands and parameter requests, and the node's loop calls
:meth:`LiveView.drain` before it processes its ROS events (every tick; in
lockstep mode from a 100 Hz timer). That hands them to the node's command
callbacks (the same intake, validation and counters as a ROS message) and to
``set_parameters_atomically`` (the same batch validation as a ROS client's
request). Imported only when ``foxglove_port`` is set.
"""
import collections
import threading

import foxglove
from rclpy.parameter import Parameter as RosParameter

from ..io import tf as TF
from ..io.foxglove_server import LiveServer, ServeError
from ..io.msgdefs import cdr_length
from ..io.topics import graph_name, SWITCH_TOPICS, TOPIC_SPECS
from .parameters import StartupError

__all__ = ['LiveView', 'Sink']

#: The topics a client may publish on (the Publish panel).
CLIENT_COMMANDS = ('torque_command', 'velocity_command', 'position_command', 'joint_commands')
#: Pending client commands and parameter requests (more are dropped and counted).
INBOX_SIZE = 1024
#: How long a parameter request of a client waits for the node's loop [s].
PARAMETER_TIMEOUT = 5.0


class Sink:
    """Where the node's messages go: the recorder, and the live view while a client subscribes."""

    def __init__(self, recorder, server):
        """Send to ``recorder`` (when it records) and ``server``."""
        self._recorder, self._server = recorder, server

    @property
    def active(self):
        """Return True while recording or while a client subscribes."""
        return self._recorder.active or self._server.subscribed

    def write(self, topic, data, log_time_ns):
        """Record and serve one message."""
        if self._recorder.active:
            self._recorder.write(topic, data, log_time_ns)
        self._server.write(topic, data, log_time_ns)


class _Request:
    """A parameter batch of a client, answered by the node's loop."""

    def __init__(self, parameters):
        self.parameters = parameters
        self.done = threading.Event()
        self.result = None


def _foxglove_value(name, value):
    if isinstance(value, float):
        return foxglove.Parameter(name, value=value, type=foxglove.ParameterType.Float64)
    if isinstance(value, (bool, int, str)):
        return foxglove.Parameter(name, value=value)
    return None


class LiveView:
    """
    The node's Foxglove server, its command and parameter inbox.

    Parameters
    ----------
    node : LeadScrewSimNode
        The node (its recorded channels, command callbacks, parameters).
    host, port : str, int
        Address to serve on.

    Raises StartupError when the server cannot start (the port is in use).

    """

    def __init__(self, node, host, port):
        """Start the server with the node's channels; serve the description."""
        self._node = node
        self._inbox = collections.deque()
        self.inbox_dropped = 0
        self.malformed = 0             # client commands that are not CDR of their type
        channels = {topic: spec[0] for topic, spec in node.recording_channels().items()}
        self._callbacks = {node.resolve_topic_name(graph_name(t)): cb
                           for t, cb in node.command_callbacks().items() if t in CLIENT_COMMANDS}
        self._types = {node.resolve_topic_name(graph_name(t)): TOPIC_SPECS[t][0]
                       for t in CLIENT_COMMANDS}
        latched = [node.resolve_topic_name(t) for t in SWITCH_TOPICS]
        desc = node._desc
        if desc is not None:
            latched += [desc.topics['robot_description'], desc.topics['/tf_static']]
        try:
            self.server = LiveServer(
                channels, host, port, name=node.get_fully_qualified_name(), latched=latched,
                commands=dict.fromkeys(self._callbacks), on_command=self._queue_command,
                parameters=self)
        except ServeError as exc:
            raise StartupError(f"parameter 'foxglove_port': {exc}") from None
        if desc is not None:
            stamp = node._sim_now()
            static = [(stamp, p, c, t, r) for p, c, t, r in desc.tree.static_transforms()]
            self.server.write(desc.topics['robot_description'], TF.encode_string(desc.urdf),
                              stamp)
            self.server.write(desc.topics['/tf_static'], TF.encode_tf_message(static), stamp)
        node.get_logger().info(f'serving Foxglove on ws://{host}:{self.server.port}')

    def sink(self, recorder):
        """Return the :class:`Sink` of ``recorder`` and this server."""
        return Sink(recorder, self.server)

    def status(self):
        """Return {name: int} of the server's counters and the inbox drops."""
        out = self.server.status()
        out['inbox_dropped'] = self.inbox_dropped
        out['malformed'] = self.malformed
        return out

    def stop(self):
        """Stop serving."""
        self.server.stop()

    def parameters_set(self, parameters):
        """Send a batch the node took (rclpy Parameters) to the clients following them."""
        values = [_foxglove_value(p.name, p.value) for p in parameters]
        self.server.publish_parameter_values([v for v in values if v is not None])

    # -- the SDK's threads -----------------------------------------------------
    def _put(self, item):
        if len(self._inbox) >= INBOX_SIZE:
            self.inbox_dropped += 1
            return False
        self._inbox.append(item)
        return True

    def _queue_command(self, topic, data):
        # DDS hands the node well-formed CDR only; a client may send anything.
        if cdr_length(self._types[topic], data) is None:
            self.malformed += 1
            return
        self._put((topic, data))

    def get(self, names):
        """Return the node's parameters named (all of them for none) as foxglove Parameters."""
        node = self._node
        names = names or sorted(node.list_parameters([], 0).names)
        out = []
        for name in names:
            if node.has_parameter(name):
                p = _foxglove_value(name, node.get_parameter(name).value)
                if p is not None:
                    out.append(p)
        return out

    def set(self, parameters):
        """Set a batch in the node's loop (whole or not at all); return the values after."""
        request = _Request([(p.name, p.get_value()) for p in parameters])
        if not self._put(request) or not request.done.wait(PARAMETER_TIMEOUT):
            self.server.publish_status('leadscrew_sim: parameters not set: the node is busy')
        elif request.result:
            self.server.publish_status(f'leadscrew_sim: parameters not set: {request.result}')
        return self.get([name for name, _v in request.parameters])

    # -- the node's loop -------------------------------------------------------
    def drain(self):
        """Hand the queued client commands and parameter batches to the node (in its loop)."""
        while self._inbox:
            item = self._inbox.popleft()
            if isinstance(item, _Request):
                item.result = self._set_parameters(item.parameters)
                item.done.set()
            else:
                self._callbacks[item[0]](item[1])

    def _set_parameters(self, pairs):
        """Set a batch through rclpy; return '' or the reason it was refused."""
        node = self._node
        try:
            params = [RosParameter(name, value=value) for name, value in pairs]
            result = node.set_parameters_atomically(params)
        except Exception as exc:  # noqa: B902 - undeclared, read-only, wrong type: the reason
            return str(exc) or type(exc).__name__
        if not result.successful:
            return result.reason
        return ''
