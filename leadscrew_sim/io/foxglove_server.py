"""
A Foxglove WebSocket server of CDR channels: the live view of the node and of ``play``.

The Foxglove SDK (``foxglove-sdk``) speaks the protocol; this module gives
it the channels (ros2msg schema, ``cdr`` encoding, the bytes as published),
serves them from a thread of its own and counts what goes wrong:

- :meth:`LiveServer.write` is called by the loop: it only appends to a
  bounded queue (``queue_size`` messages) when a client subscribes to the
  topic; a full queue drops the message and counts it (``queue_dropped``);
- the serving thread hands the queue to the SDK every ``period`` seconds.
  The SDK keeps an outbox of ``backlog`` messages per client and drops the
  oldest of a client that does not read; it gives no count of those drops,
  only a log line at most every 30 s, counted here (``outbox_full_reports``);
- frames the SDK refuses (not JSON, unknown opcodes, unknown channel ids) are
  counted from its error log (``bad_frames``, ``unknown_channels``); client
  messages over :data:`MAX_CLIENT_MESSAGE` bytes (``oversized``) and on
  topics or encodings not taken (``refused``) are counted here.

Latched topics (robot_description, /tf_static, the switches) keep their last
message, sent again to every subscriber when a client subscribes.

Importing this module imports the SDK: the node and ``play`` import it only
when a Foxglove port is given. Nothing here imports rclpy.
"""
import collections
import logging
import threading
import time

import foxglove
from foxglove import Channel, Context, Schema
from foxglove.websocket import Capability, ServerListener

from .msgdefs import ros2msg_definition
from ..core.errors import LeadscrewError

__all__ = ['BACKLOG', 'LiveServer', 'MAX_CLIENT_MESSAGE', 'QUEUE_SIZE', 'ServeError']

#: Messages between the loop and the serving thread (about 1 s of the node's topics at 1 kHz).
QUEUE_SIZE = 8192
#: The SDK's outbox per client [messages] (its default).
BACKLOG = 1024
#: The largest message a client may publish [bytes] (a JointState of a few joints is ~100).
MAX_CLIENT_MESSAGE = 65536
#: How often the serving thread hands the queue to the SDK [s].
PERIOD = 0.005

#: SDK log lines counted, by their start: counter name.
_SDK_LINES = (('Invalid message', 'bad_frames'),
              ('Received message for unknown channel', 'unknown_channels'),
              ('outbox for client', 'outbox_full_reports'))


class ServeError(LeadscrewError, OSError):
    """The server cannot start (the port is in use, a bad address); the message is one line."""


class _SdkLogCounter(logging.Handler):
    """Count the SDK's log lines about refused frames and full outboxes (not printed)."""

    def __init__(self, counts):
        super().__init__(logging.INFO)
        self.counts = counts

    def emit(self, record):
        msg = record.getMessage()
        for start, name in _SDK_LINES:
            if msg.startswith(start):
                self.counts[name] += 1
                return
        if record.levelno >= logging.ERROR:
            self.counts['sdk_errors'] += 1


def _listen_to_sdk_log(counts):
    """Route the SDK's log (``foxglove.*`` loggers) to a counter instead of stderr."""
    log = logging.getLogger('foxglove')
    for h in list(log.handlers):
        if isinstance(h, _SdkLogCounter):
            log.removeHandler(h)
    log.addHandler(_SdkLogCounter(counts))
    log.setLevel(logging.INFO)
    log.propagate = False


def _normal_topic(topic):
    return topic.lstrip('/')


class LiveServer(ServerListener):
    """
    Serve CDR channels over the Foxglove WebSocket protocol (see the module docstring).

    Parameters
    ----------
    channels : dict
        Topic (as advertised) -> ROS type name (``'sensor_msgs/msg/JointState'``:
        its installed ros2msg definition) or (type name, schema encoding, schema
        bytes) as a recording carries them.
    host, port : str, int
        Address to bind (port 0: any free port, see :attr:`port`).
    name : str
        Server name shown by the client.
    latched : iterable of str
        Topics whose last message every new subscriber gets.
    commands : dict, optional
        Topic a client may publish (without or with a leading ``/``) -> type name;
        with ``on_command(topic, data)``, called on the SDK's thread.
    parameters : object, optional
        ``get(names) -> [foxglove.Parameter]`` and ``set([foxglove.Parameter]) ->
        [foxglove.Parameter]``, called on the SDK's thread (the parameter panel).
    queue_size, backlog : int
        The serving queue and the SDK's outbox per client [messages].
    playback_range : tuple of int, optional
        (start, end) [ns] of a recording being served.

    """

    def __init__(self, channels, host, port, name, latched=(), commands=None,
                 on_command=None, parameters=None, queue_size=QUEUE_SIZE, backlog=BACKLOG):
        """Create the channels and start the server and its serving thread."""
        self.counts = collections.Counter()
        _listen_to_sdk_log(self.counts)
        self._context = Context()
        self._channels, self._topic_of = {}, {}
        for topic, spec in channels.items():
            if isinstance(spec, str):
                spec = (spec, 'ros2msg', ros2msg_definition(spec).encode())
            schema = Schema(name=spec[0], encoding=spec[1], data=bytes(spec[2]))
            ch = Channel(topic, schema=schema, message_encoding='cdr', context=self._context)
            self._channels[topic] = ch
            self._topic_of[ch.id()] = topic
        self._subs = dict.fromkeys(channels, 0)       # topic -> subscriptions
        self._latched = {t: None for t in latched if t in channels}
        self._commands = {_normal_topic(t): t for t in (commands or {})}
        self._on_command = on_command
        self._parameters = parameters
        self._client_channels = {}                    # (client id, channel id) -> topic or None
        self._queue = collections.deque()
        self.queue_size = queue_size
        self.backlog = backlog
        caps = []
        if self._commands:
            caps.append(Capability.ClientPublish)
        if parameters is not None:
            caps.append(Capability.Parameters)
        try:
            self._server = foxglove.start_server(
                name=name, host=host, port=port, capabilities=caps, server_listener=self,
                supported_encodings=['cdr'] if self._commands else None,
                context=self._context, message_backlog_size=backlog)
        except (RuntimeError, OSError, ValueError, OverflowError) as exc:
            text = str(exc).replace('FoxgloveError: ', '')
            raise ServeError(f'cannot serve Foxglove on {host}:{port}: {text}') from None
        self.host, self.port = host, self._server.port
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._serve, name='foxglove-serve', daemon=True)
        self._thread.start()

    # -- the loop's side -------------------------------------------------------
    @property
    def subscribed(self):
        """Return True while a client subscribes to any channel."""
        return self.counts['subscriptions'] > 0

    def write(self, topic, data, log_time_ns):
        """Queue one message for the subscribers of ``topic`` (never blocks; drops when full)."""
        if topic in self._latched:
            self._latched[topic] = (data, log_time_ns)
        if not self._subs.get(topic):
            return
        if len(self._queue) >= self.queue_size:
            self.counts['queue_dropped'] += 1
            return
        self._queue.append((topic, data, log_time_ns))

    def status(self):
        """Return {name: int} of the counters (see the module docstring)."""
        out = {k: self.counts[k] for k in (
            'subscriptions', 'sent', 'queue_dropped', 'outbox_full_reports', 'bad_frames',
            'unknown_channels', 'oversized', 'refused', 'client_messages', 'sdk_errors')}
        out['queued'] = len(self._queue)
        return out

    def publish_status(self, message, error=True):
        """Show a status line (an error or a note) in every client."""
        level = foxglove.StatusLevel.Error if error else foxglove.StatusLevel.Info
        self._server.publish_status(message, level)

    def publish_parameter_values(self, parameters):
        """Send changed parameters ([foxglove.Parameter]) to the clients that follow them."""
        self._server.publish_parameter_values(parameters)

    def wait_sent(self, timeout):
        """Wait up to ``timeout`` [s] until the queue is handed to the SDK; return True if so."""
        end = time.monotonic() + timeout
        while self._queue and time.monotonic() < end:
            time.sleep(PERIOD)
        time.sleep(2 * PERIOD)            # the last batch
        return not self._queue

    def stop(self):
        """Stop the serving thread and the server."""
        self._stop.set()
        self._thread.join(timeout=2.0)
        self._server.stop()

    def _serve(self):
        q, channels, counts = self._queue, self._channels, self.counts
        while not self._stop.is_set():
            time.sleep(PERIOD)
            n = 0
            while q:
                topic, data, log_time = q.popleft()
                channels[topic].log(data, log_time=log_time)
                n += 1
            counts['sent'] += n

    # -- the SDK's callbacks (its threads) -------------------------------------
    def on_subscribe(self, client, channel):
        """Count the subscription; send a latched topic's last message again."""
        topic = self._topic_of.get(channel.id)
        if topic is None:
            return
        self._subs[topic] += 1
        self.counts['subscriptions'] += 1
        last = self._latched.get(topic)
        if last is not None:
            self._queue.append((topic, last[0], last[1]))   # past the bound: one message

    def on_unsubscribe(self, client, channel):
        """Count the subscription gone (also when the client leaves)."""
        topic = self._topic_of.get(channel.id)
        if topic is not None and self._subs[topic] > 0:
            self._subs[topic] -= 1
            self.counts['subscriptions'] -= 1

    def on_client_advertise(self, client, channel):
        """Take a client channel on a command topic with the cdr encoding."""
        topic = self._commands.get(_normal_topic(channel.topic))
        if channel.encoding != 'cdr':
            topic = None
        self._client_channels[(client.id, channel.id)] = topic
        if topic is None:
            self.publish_status(f'leadscrew_sim: {channel.topic!r} ({channel.encoding}) is not '
                                'taken; publish cdr on: ' + ', '.join(sorted(self._commands)))

    def on_client_unadvertise(self, client, client_channel_id):
        """Forget a client channel."""
        self._client_channels.pop((client.id, client_channel_id), None)

    def on_message_data(self, client, client_channel_id, data):
        """Hand a command to ``on_command``; count oversized and refused messages."""
        self.counts['client_messages'] += 1
        key = (client.id, client_channel_id)
        if key not in self._client_channels:
            self.counts['unknown_channels'] += 1
            return
        topic = self._client_channels[key]
        if len(data) > MAX_CLIENT_MESSAGE:
            self.counts['oversized'] += 1
            return
        if topic is None or self._on_command is None:
            self.counts['refused'] += 1
            return
        self._on_command(topic, bytes(data))

    def on_get_parameters(self, client, param_names, request_id=None):
        """Return the parameters asked for (all for an empty list)."""
        if self._parameters is None:
            return []
        return self._parameters.get(list(param_names))

    def on_set_parameters(self, client, parameters, request_id=None):
        """Set a batch of parameters; return their values afterwards."""
        if self._parameters is None:
            return []
        return self._parameters.set(list(parameters))
