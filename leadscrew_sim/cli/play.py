"""
``play``: republish the messages of any ros2-profile recording with their timing.

On the ROS graph (rclpy is imported when it runs), or with ``--foxglove PORT``
to Foxglove over its WebSocket protocol, without ROS
(:mod:`leadscrew_sim.offline.play.foxglove`).
"""
import math
import sys
import time

from .args import add_deprecated_alias, PROG, UsageError
from ..offline.options import NS, open_recording, RunError
from ..core import yamlio
from ..io import messages as M
from ..offline.play.schedule import Sleeper

HELP = 'republish a recording with its timing'

#: Pause after the subscribers matched [s] (the readers' side of discovery).
PLAY_SETTLE_S = 0.25
#: Longest wait for the subscribers' acknowledgements at the end [s].
PLAY_ACK_TIMEOUT_S = 5.0


def add_arguments(p):
    """Add the options of ``play`` to parser ``p``."""
    p.add_argument('file', help='the recording (any ros2-profile MCAP file or rosbag2 bag)')
    p.add_argument('--speed-factor', dest='rate', type=float, default=1.0, metavar='F',
                   help='playback speed relative to the recorded log times [-] (default 1; '
                   '0.5: half speed)')
    add_deprecated_alias(p, '--rate', '--speed-factor', 'rate', float)
    p.add_argument('--topics', nargs='+', help='only these (recorded) topics')
    p.add_argument('--remap', action='append', metavar='FROM:=TO',
                   help='publish recorded topic FROM on TO (repeatable)')
    p.add_argument('--loop', action='store_true', help='play the recording again and again')
    p.add_argument('--clock', action='store_true', help='publish /clock from the log time')
    p.add_argument('--wait-subscribers', type=int, default=1, metavar='N',
                   help='wait until N subscriptions matched in total (default 1)')
    p.add_argument('--wait-timeout', type=float, default=2.0, metavar='S',
                   help='longest wait for subscribers [s] (default 2)')
    p.add_argument('--foxglove', type=int, metavar='PORT',
                   help='serve the recording to Foxglove on this TCP port (1-65535) instead of '
                   'the ROS graph (no ROS needed); --wait-subscribers then counts Foxglove '
                   'subscriptions')
    p.add_argument('--foxglove-host', default='127.0.0.1', metavar='ADDR',
                   help='address to serve Foxglove on (default 127.0.0.1)')
    p.add_argument('--quiet', '-q', action='store_true',
                   help='no summary line (warnings and errors only)')


def _message_class(msg_type):
    """Return the Python class of 'pkg/msg/Type'."""
    try:
        from rosidl_runtime_py.utilities import get_message
        return get_message(msg_type)
    except ImportError:
        pass
    import importlib
    parts = msg_type.split('/')
    if len(parts) == 2:
        parts = [parts[0], 'msg', parts[1]]
    if len(parts) != 3:
        raise RunError(f'unsupported message type name {msg_type!r}')
    try:
        return getattr(importlib.import_module(f'{parts[0]}.{parts[1]}'), parts[2])
    except (ImportError, AttributeError):
        raise RunError(f'message type {msg_type!r} is not installed') from None


def _qos_from_metadata(metadata):
    """Return a QoSProfile from a channel's offered_qos_profiles (reliable, depth 10 default)."""
    from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
    rel, dur, depth = ReliabilityPolicy.RELIABLE, DurabilityPolicy.VOLATILE, 10
    try:
        profiles = yamlio.load(metadata.get('offered_qos_profiles', '')) or []
        if profiles and isinstance(profiles[0], dict):
            pr = profiles[0]
            if pr.get('reliability') in ('best_effort', 2):
                rel = ReliabilityPolicy.BEST_EFFORT
            if pr.get('durability') in ('transient_local', 1):
                dur = DurabilityPolicy.TRANSIENT_LOCAL
            depth = max(1, int(pr.get('depth') or 10))
    except (yamlio.YAMLError, ValueError, TypeError, AttributeError):
        pass
    return QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=max(depth, 100), reliability=rel,
                      durability=dur)


def _parse_remaps(items):
    """Return {from: to} of the ``--remap from:=to`` options."""
    remap = {}
    for item in items or ():
        src, sep, dst = item.partition(':=')
        if not sep or not src or not dst:
            raise RunError(f'--remap {item!r}: expected from:=to')
        remap[src] = dst
    return remap


def run(args):
    """Republish a recording with its original timing; return the exit status."""
    if not (math.isfinite(args.rate) and args.rate > 0):
        raise RunError(f'--speed-factor {args.rate} must be > 0')
    if args.foxglove is not None and not 1 <= args.foxglove <= 65535:
        raise UsageError(f'--foxglove {args.foxglove}: a TCP port, 1-65535')
    rec = open_recording(args.file, topics=args.topics)
    rec.require_ros2()
    remap = _parse_remaps(args.remap)
    if args.topics:
        unknown = [t for t in args.topics if t not in rec.topic_types]
        if unknown:
            raise RunError(f'--topics: not in the file: {", ".join(unknown)} (topics: '
                           f'{", ".join(sorted(rec.topic_types))})')
    if not rec.messages:
        raise RunError(f'{args.file}: no messages to play')
    if args.foxglove is not None:
        return _serve_foxglove(args, rec, remap)
    used = sorted({m[1] for m in rec.messages})
    chan_meta = {c.topic: dict(c.metadata) for c in rec.channels.values()}
    classes = {}
    for t in used:
        try:
            classes[t] = _message_class(rec.topic_types[t])
        except RunError as exc:
            if args.topics:          # asked for by name: an error
                raise
            print(f'{PROG}: warning: skipping {t}: {exc}', file=sys.stderr)
    if not classes:
        raise RunError(f'{args.file}: no topic of an installed message type to play')
    used = sorted(classes)
    rec.messages = [m for m in rec.messages if m[1] in classes]
    import rclpy
    context = rclpy.Context()
    rclpy.init(args=[], context=context)
    node = None
    try:
        node = rclpy.create_node('leadscrew_sim_player', context=context)
        pubs = {t: node.create_publisher(classes[t], remap.get(t, t),
                                         _qos_from_metadata(chan_meta.get(t, {})))
                for t in used}
        clock_pub = None
        if args.clock:
            from rclpy.qos import QoSProfile
            from rosgraph_msgs.msg import Clock
            clock_pub = node.create_publisher(Clock, '/clock', QoSProfile(depth=10))
        _wait_for_subscribers(args, pubs)
        sent, wall = _publish(args, rec, pubs, clock_pub)
        _finish(args, pubs, sent, wall)
    except KeyboardInterrupt:
        print(f'{PROG}: interrupted', file=sys.stderr)
        return 130
    finally:
        if node is not None:
            node.destroy_node()
        if context.ok():
            rclpy.shutdown(context=context)
    return 0


def _serve_foxglove(args, rec, remap):
    """Serve the recording to Foxglove (the SDK is imported only here); return 0."""
    from ..io.foxglove_server import ServeError
    from ..offline.play.foxglove import serve_recording
    try:
        sent, wall = serve_recording(rec, args, remap, M.StateEncoder().clock)
    except ServeError as exc:
        raise UsageError(f'--foxglove {args.foxglove}: {exc}') from None
    except KeyboardInterrupt:
        print(f'{PROG}: interrupted', file=sys.stderr)
        return 130
    if not args.quiet:
        print(f'served {sent} messages on {len({m[1] for m in rec.messages})} topics in '
              f'{wall:.3f} s (speed factor {args.rate:g})')
    return 0


def _wait_for_subscribers(args, pubs):
    """Wait up to ``--wait-timeout`` s until ``--wait-subscribers`` subscriptions matched."""
    end = time.monotonic() + args.wait_timeout
    while time.monotonic() < end:
        matched = sum(p.get_subscription_count() for p in pubs.values())
        if matched >= args.wait_subscribers:
            # Discovery is two-sided: the subscription can be matched here
            # before its reader has matched this writer, and a message sent
            # in between is not delivered. Give the other side a moment.
            time.sleep(PLAY_SETTLE_S)
            return
        time.sleep(0.01)
    if args.wait_subscribers:
        print(f'{PROG}: warning: {matched} of {args.wait_subscribers} subscribers '
              f'after {args.wait_timeout:g} s; playing anyway', file=sys.stderr)


def _publish(args, rec, pubs, clock_pub):
    """Publish the messages on their schedule; return (messages sent, wall time [s])."""
    clock_enc = M.StateEncoder().clock
    sleeper = Sleeper()
    t_first = rec.messages[0][0]
    scale = 1.0 / args.rate
    sent = 0
    t_wall0 = time.monotonic_ns()
    while True:
        start = time.monotonic_ns() + 1_000_000
        for log_time, topic, data in rec.messages:
            sleeper.until(start + int((log_time - t_first) * scale))
            if clock_pub is not None:
                clock_pub.publish(clock_enc(log_time, ()))
            pubs[topic].publish(data)
            sent += 1
        if not args.loop:
            break
    return sent, (time.monotonic_ns() - t_wall0) / NS


def _finish(args, pubs, sent, wall):
    """Wait for the acknowledgements of the reliable subscribers and print the summary."""
    # Reliable writers: wait until the subscribers acknowledged the tail
    # before the node (and its history) is destroyed.
    from rclpy.duration import Duration
    unacked = [t for t, p in pubs.items()
               if not p.wait_for_all_acked(Duration(seconds=PLAY_ACK_TIMEOUT_S))]
    if not args.quiet:
        print(f'published {sent} messages on {len(pubs)} topics in {wall:.3f} s '
              f'(speed factor {args.rate:g})')
    if unacked:
        print(f'{PROG}: warning: not acknowledged within {PLAY_ACK_TIMEOUT_S:g} s on '
              f'{", ".join(unacked)}', file=sys.stderr)
