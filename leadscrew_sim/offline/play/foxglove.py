"""
``play``'s ``foxglove`` option: serve a recording over Foxglove's WebSocket protocol, no ROS.

The recording's channels are advertised with the schemas the file carries
(ros2msg for a ros2 recording) and the ``cdr`` encoding; the messages go out
with their recorded bytes and log times, on the recorded schedule scaled by
the speed factor. Latched channels (transient local in the recording: in the
node's recordings robot_description and /tf_static) are sent again to every
new subscriber, so the 3D panel shows the axis whenever a client connects.
"""
import sys
import time

from ...core import yamlio
from ...io.foxglove_server import LiveServer
from ...io.msgdefs import ros2msg_definition, DefinitionNotFoundError
from ..options import NS, RunError
from .schedule import Sleeper

__all__ = ['serve_recording']

#: The /clock type (the ``clock`` option).
CLOCK_TYPE = 'rosgraph_msgs/msg/Clock'


def _latched(metadata):
    """Return True if a channel's offered QoS is transient local."""
    try:
        profiles = yamlio.load(metadata.get('offered_qos_profiles', '')) or []
        return bool(profiles) and isinstance(profiles[0], dict) and (
            profiles[0].get('durability') in ('transient_local', 1))
    except (yamlio.YAMLError, ValueError, TypeError, AttributeError):
        return False


def _channels(rec, topics, remap):
    """Return ({served topic: (type, schema encoding, schema)}, [latched served topics])."""
    channels, latched = {}, []
    for ch in rec.channels.values():
        if ch.topic not in topics or remap.get(ch.topic, ch.topic) in channels:
            continue
        served = remap.get(ch.topic, ch.topic)
        schema = rec.schemas.get(ch.schema_id)
        if schema is not None and schema.data:
            channels[served] = (schema.name, schema.encoding, schema.data)
        else:                       # a bag without definitions: the installed one
            type_name = rec.topic_types.get(ch.topic, '')
            try:
                channels[served] = (type_name, 'ros2msg', ros2msg_definition(type_name).encode())
            except (DefinitionNotFoundError, ValueError) as exc:
                raise RunError(f'{ch.topic}: the recording has no schema for {type_name!r} and '
                               f'none is installed ({exc})') from None
        if _latched(dict(ch.metadata)):
            latched.append(served)
    return channels, latched


def serve_recording(rec, args, remap, clock_enc, out=sys.stdout):
    """
    Serve ``rec`` (its ``messages`` already filtered) to Foxglove; return (sent, wall [s]).

    Raises :class:`~leadscrew_sim.io.foxglove_server.ServeError` when the
    port cannot be bound.

    ``args``: ``foxglove`` (port), ``foxglove_host``, ``rate`` (speed factor),
    ``loop``, ``clock``, ``wait_subscribers`` (subscriptions to wait for),
    ``wait_timeout`` [s], ``quiet``. ``clock_enc(stamp, ())`` encodes /clock.
    """
    topics = {m[1] for m in rec.messages}
    channels, latched = _channels(rec, topics, remap)
    if args.clock:
        try:
            channels['/clock'] = (CLOCK_TYPE, 'ros2msg', ros2msg_definition(CLOCK_TYPE).encode())
        except DefinitionNotFoundError as exc:
            raise RunError(f'<<clock>>: {exc}') from None
    server = LiveServer(channels, args.foxglove_host, args.foxglove, name='leadscrew_sim play',
                        latched=latched)      # ServeError: the port is in use
    try:
        if not args.quiet:
            print(f'serving {len(channels)} topics on ws://{args.foxglove_host}:{server.port}',
                  file=out, flush=True)
        _wait_for_subscribers(server, args)
        # The latched messages, once, before the schedule (a late subscriber gets them too).
        first = {}
        for log_time, topic, data in rec.messages:
            if remap.get(topic, topic) in latched and topic not in first:
                first[topic] = True
                server.write(remap.get(topic, topic), data, log_time)
        sent, wall = _play(server, rec, remap, args, clock_enc)
        server.wait_sent(5.0)
        status = server.status()
    finally:
        server.stop()
    if status['queue_dropped']:
        print(f'leadscrew_sim: warning: {status["queue_dropped"]} messages dropped (the serving '
              'queue was full)', file=sys.stderr)
    return sent, wall


def _wait_for_subscribers(server, args):
    end = time.monotonic() + args.wait_timeout
    while time.monotonic() < end:
        if server.status()['subscriptions'] >= args.wait_subscribers:
            return
        time.sleep(0.01)
    if args.wait_subscribers:
        print(f'leadscrew_sim: warning: {server.status()["subscriptions"]} of '
              f'{args.wait_subscribers} subscriptions after {args.wait_timeout:g} s; '
              'playing anyway', file=sys.stderr)


def _play(server, rec, remap, args, clock_enc):
    sleeper = Sleeper()
    t_first = rec.messages[0][0]
    scale = 1.0 / args.rate
    names = {t: remap.get(t, t) for t in {m[1] for m in rec.messages}}
    sent = 0
    t_wall0 = time.monotonic_ns()
    while True:
        start = time.monotonic_ns() + 1_000_000
        for log_time, topic, data in rec.messages:
            sleeper.until(start + int((log_time - t_first) * scale))
            if args.clock:
                server.write('/clock', clock_enc(log_time, ()), log_time)
            server.write(names[topic], data, log_time)
            sent += 1
        if not args.loop:
            break
    return sent, (time.monotonic_ns() - t_wall0) / NS
