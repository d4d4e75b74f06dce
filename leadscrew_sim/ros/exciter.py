"""
The exciter: a small rclpy node that publishes an excitation profile as commands of the axis.

It publishes the profile's command (std_msgs/Float64 on ``torque_command``,
``velocity_command`` or ``position_command``, or sensor_msgs/JointState on
``joint_commands`` for the ``<prefix>screw_joint`` / ``<prefix>nut_joint``)
in its namespace, at a fixed rate on a wall-clock (steady) timer. The k-th
message carries the profile's value at k / rate seconds after the start,
where k counts the periods elapsed, so a late timer skips values instead of
stretching the profile. It waits for a subscriber first, prints its progress
at each segment, and ends with the profile's last value. For the breakaway
ramps it follows ``nut_position`` to end a ramp once the nut moved (the
profile's ``controller``); without that topic the ramps run as planned.
"""
import math
import signal
import time

from ..analysis.excitation.base import KIND_TOPICS
from ..io.topics import graph_name, resolve, TOPIC_SPECS
from ..core.errors import LeadscrewError

__all__ = ['ExciteError', 'Exciter']

#: Pause after a subscriber matched [s]: discovery is two-sided, the subscriber's
#: reader may not have matched this writer yet.
SETTLE_S = 0.25
#: Longest wait for the acknowledgement of the last messages [s].
ACK_TIMEOUT_S = 5.0


class ExciteError(LeadscrewError, RuntimeError):
    """A failure of the exciter the user can act on (no subscriber, bad namespace)."""


class Exciter:
    """
    Publish the commands of one profile to the node (or a real axis) over ROS.

    Parameters
    ----------
    profile : leadscrew_sim.analysis.excitation.profiles.Profile
        What to publish.
    rate : float
        Messages per second [Hz].
    namespace : str
        Namespace of the exciter node: the node's topics are resolved in it.
    joint_commands : bool
        Publish sensor_msgs/JointState on ``joint_commands`` instead of Float64.
    prefix : str
        Joint name prefix (``joint_commands`` only).
    out : callable
        Where the progress lines go (``print``).
    log : callable, optional
        ``log(k, t, value)`` for every message sent: index, profile time [s], value.

    """

    def __init__(self, profile, rate, namespace='', joint_commands=False, prefix='',
                 out=print, log=None):
        """Keep the settings; nothing of ROS starts yet."""
        self.profile, self.rate = profile, float(rate)
        self.namespace = namespace
        self.joint_commands, self.prefix = joint_commands, prefix
        self.out, self.log = out, log
        self.mixed = profile.kind == 'mixed'        # commission: a topic per part
        first = profile.parts[0][2] if self.mixed else profile
        self.topic = 'joint_commands' if joint_commands else first.topic
        self.sent = 0
        self.stop = False
        #: System time [ns] of the first command sent (None before): the segments sidecar's
        #: time base.
        self.start_ns = None

    def _kind(self, t):
        """Return the command kind at profile time ``t`` [s]."""
        return self.profile.kind_at(t) if self.mixed else self.profile.kind

    def _topics(self):
        """Return the command topics the profile publishes on."""
        if self.joint_commands:
            return ['joint_commands']
        return self.profile.topics if self.mixed else [self.profile.topic]

    def _message(self, value, kind=None):
        """Return the message of one command value (of ``kind``, default the profile's)."""
        if not self.joint_commands:
            from std_msgs.msg import Float64
            return Float64(data=float(value))
        from sensor_msgs.msg import JointState
        kind = kind or self.profile.kind
        if kind == 'torque':
            return JointState(name=[self.prefix + 'screw_joint'], effort=[float(value)])
        msg = JointState(name=[self.prefix + 'nut_joint'])
        if kind == 'velocity':
            msg.velocity = [float(value)]
        else:
            msg.position = [float(value)]
        return msg

    def run(self, wait_timeout=10.0):
        """
        Wait for a subscriber, publish the whole profile, return the exit code (0; 130 on Ctrl-C).

        Parameters
        ----------
        wait_timeout : float
            Longest wait for a subscriber [s]; ExciteError after it.

        """
        import rclpy
        from rclpy.signals import SignalHandlerOptions
        context = rclpy.Context()
        rclpy.init(args=[], context=context, signal_handler_options=SignalHandlerOptions.NO)
        node = None
        old = {s: signal.getsignal(s) for s in (signal.SIGINT, signal.SIGTERM)}

        def on_signal(_signum, _frame):
            self.stop = True

        for s in old:
            signal.signal(s, on_signal)
        try:
            try:
                node = rclpy.create_node('leadscrew_sim_exciter', namespace=self.namespace or '/',
                                         context=context)
            except Exception as exc:  # noqa: B902 - rclpy's invalid-name errors vary
                raise ExciteError(f'--namespace {self.namespace!r}: '
                                  f'{" ".join(str(exc).split())}') from None
            return self._run(node, context, wait_timeout)
        finally:
            for s, handler in old.items():
                signal.signal(s, handler)
            if node is not None:
                node.destroy_node()
            if context.ok():
                rclpy.shutdown(context=context)

    def _run(self, node, context, wait_timeout):
        """Create the publishers and the executor, then publish; return the exit code."""
        from rclpy.executors import SingleThreadedExecutor
        from std_msgs.msg import Float64
        from .interfaces import message_class, qos_profile
        pubs = {}
        for topic in self._topics():
            msg_type, _role, qos = TOPIC_SPECS[topic]
            pubs[topic] = node.create_publisher(message_class(msg_type), graph_name(topic),
                                                qos_profile(qos))
        pub = pubs[self.topic]
        name = resolve(self.topic, node.get_namespace())
        latest = {'x': None}
        sub = node.create_subscription(Float64, 'nut_position',
                                       lambda m: latest.__setitem__('x', m.data),
                                       qos_profile(TOPIC_SPECS['nut_position'][2]))
        executor = SingleThreadedExecutor(context=context)
        executor.add_node(node)
        try:
            return self._publish(node, executor, pubs, pub, sub, latest, name, wait_timeout)
        finally:
            # shut down before the context is: a collected executor's __del__ after
            # rclpy.shutdown raises (printed as an ignored exception)
            executor.shutdown()

    def _publish(self, node, executor, pubs, pub, sub, latest, name, wait_timeout):
        """Wait for the axis, publish the profile; return the exit code."""
        from rclpy.clock import Clock, ClockType
        from rclpy.duration import Duration
        self.out(f'excite: {self.profile.describe()}; {self.profile.duration:.3f} s at '
                 f'{self.rate:g} Hz on {name}')
        if self._wait_for_axis(node, executor, pub, sub, latest, name, wait_timeout):
            return 130
        ctl = self.profile.controller()
        state = {'k': -1, 'segment': -1, 'done': False}
        t0 = time.monotonic()
        n_last = int(math.ceil(self.profile.duration * self.rate - 1e-9))

        def tick():
            k = min(int((time.monotonic() - t0) * self.rate), n_last)
            if k <= state['k'] or state['done']:
                return
            state['k'] = k
            t = k / self.rate
            value = ctl(t, latest['x'])
            kind = self._kind(t)
            topic = 'joint_commands' if self.joint_commands else KIND_TOPICS[kind]
            pubs[topic].publish(self._message(value, kind))
            if self.start_ns is None:
                self.start_ns = time.time_ns()
            self.sent += 1
            if self.log is not None:
                self.log(k, t, value)
            seg = self.profile.segment_at(t)
            if seg != state['segment']:
                state['segment'] = seg
                s = self.profile.segments[seg]
                unit = self.profile.unit_at(t) if self.mixed else self.profile.unit
                self.out(f'excite: t={t:8.3f} s  segment {seg + 1}/'
                         f'{len(self.profile.segments)} {s.label}  command {value:+.6g} '
                         f'{unit}')
            state['done'] = k >= n_last

        timer = node.create_timer(1.0 / self.rate, tick,
                                  clock=Clock(clock_type=ClockType.STEADY_TIME))
        tick()
        while not state['done'] and not self.stop:
            executor.spin_once(timeout_sec=0.05)
        timer.cancel()
        if self.stop:
            t_end = self.profile.duration
            kind = self._kind(t_end)
            if kind != 'position':     # a position target holds by itself
                topic = 'joint_commands' if self.joint_commands else KIND_TOPICS[kind]
                pubs[topic].publish(self._message(self.profile(t_end), kind))
            self.out(f'excite: interrupted after {self.sent} commands (sent the rest value '
                     'of a torque or speed profile)')
            return 130
        if not all(p.wait_for_all_acked(Duration(seconds=ACK_TIMEOUT_S))
                   for p in pubs.values()):
            self.out(f'excite: warning: the last commands were not acknowledged within '
                     f'{ACK_TIMEOUT_S:g} s')
        self.out(f'excite: done, {self.sent} commands in {time.monotonic() - t0:.3f} s')
        return 0

    def _wait_for_axis(self, node, executor, pub, sub, latest, name, wait_timeout):
        """Wait for a subscriber and the axis's first nut_position; return True if stopped."""
        end = time.monotonic() + wait_timeout
        while pub.get_subscription_count() == 0:
            if self.stop:
                return True
            if time.monotonic() > end:
                raise ExciteError(f'no subscriber on {name} after {wait_timeout:g} s (is '
                                  'the node running, in this ROS_DOMAIN_ID and namespace?)')
            executor.spin_once(timeout_sec=0.01)
        # A node that subscribed may not run its loop yet (start-up): commands sent
        # then overflow the subscription's history. Its first nut_position shows the
        # loop runs; an axis without that topic gets the settling pause only.
        settle_end = time.monotonic() + SETTLE_S
        while time.monotonic() < settle_end or (
                latest['x'] is None and node.count_publishers(sub.topic_name) > 0
                and time.monotonic() < end):
            if self.stop:
                return True
            executor.spin_once(timeout_sec=0.01)
        kinds = {p.kind for _n, _t, p in self.profile.parts} if self.mixed else {
            self.profile.kind}
        if 'torque' not in kinds:
            node.destroy_subscription(sub)         # only the breakaway ramps follow the nut
        if 'torque' in kinds and latest['x'] is None:
            self.out('excite: no nut_position received: the ramps run as planned, without '
                     'the stop at abort_travel')
        return False
