"""
Helpers shared by the test modules of every layer (``import helpers``).

Repository paths (REPO, SHARED: ../shared, which may be absent), time and
QoS constants, a leadscrew_sim executable as a real subprocess (NodeProcess),
the offline CLI runner, and the test-side rclpy helper (Ros) with the node
start and wait helpers of the ROS layer's tests. ROS is imported only where
it is used (Ros, DEEP, command_publisher, publish_until, param_msg), so the core, io and
cli tests run without loading rclpy.
"""
import os
from pathlib import Path
import signal
import subprocess
import sys
import time
import uuid

#: The repository root.
REPO = Path(__file__).resolve().parents[1]
#: The shared tools and data next to the repository; tests that need them skip without.
SHARED = REPO.parent / 'shared'

#: Nanoseconds per second and per millisecond.
NS = 1_000_000_000
MS = 1_000_000
#: Fully qualified name of the simulator node.
NODE = '/leadscrew_sim_node'


def _deep():
    """Return DEEP, a reliable QoS profile of depth 1000 (built on first use: needs rclpy)."""
    if 'DEEP' not in globals():
        from rclpy.qos import QoSProfile, ReliabilityPolicy
        globals()['DEEP'] = QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE)
    return globals()['DEEP']


def __getattr__(name):
    """Provide DEEP (``from helpers import DEEP``) without importing rclpy at import time."""
    if name == 'DEEP':
        return _deep()
    raise AttributeError(f'module {__name__!r} has no attribute {name!r}')


def wait_for(predicate, timeout, period=0.02):
    """Poll predicate until true or timeout; return its last value."""
    end = time.monotonic() + timeout
    while True:
        value = predicate()
        if value or time.monotonic() > end:
            return value
        time.sleep(period)


class NodeProcess:
    """A leadscrew_sim executable running as a real subprocess."""

    def __init__(self, argv, log_path):
        self.log_path = log_path
        self._log = open(log_path, 'wb')
        self.proc = subprocess.Popen(
            argv, stdout=self._log, stderr=subprocess.STDOUT,
            env=dict(os.environ, PYTHONFAULTHANDLER='1'), start_new_session=True)

    def output(self):
        """Return everything the process printed so far."""
        self._log.flush()
        return Path(self.log_path).read_text(errors='replace')

    def send(self, sig):
        """Send a signal to the process."""
        if self.proc.poll() is None:
            self.proc.send_signal(sig)

    def wait(self, timeout):
        """
        Wait for exit and return the exit code.

        A process still running after timeout is aborted (SIGABRT: the fault handler prints
        every thread's Python stack) and the test fails with its output, so a hang shows
        where it hung.
        """
        try:
            return self.proc.wait(timeout=timeout)
        except subprocess.TimeoutExpired:
            self.proc.send_signal(signal.SIGABRT)
            try:
                self.proc.wait(timeout=10)
            except subprocess.TimeoutExpired:
                os.killpg(self.proc.pid, signal.SIGKILL)
            raise AssertionError(f'{self.proc.args} still ran after {timeout} s; its output, '
                                 f'with the stacks at the abort:\n{self.output()}') from None

    def stop(self, sig=signal.SIGINT, timeout=15.0):
        """Stop cleanly with sig; kill the group if it does not exit."""
        if self.proc.poll() is None:
            self.proc.send_signal(sig)
            try:
                self.proc.wait(timeout=timeout)
            except subprocess.TimeoutExpired:
                os.killpg(self.proc.pid, signal.SIGKILL)
                self.proc.wait(timeout=5)
        self._log.close()
        return self.proc.returncode


def cli(*args, timeout=300):
    """Run ``python -m leadscrew_sim.cli``; return the CompletedProcess (text)."""
    return subprocess.run([sys.executable, '-m', 'leadscrew_sim.cli', *map(str, args)],
                          capture_output=True, text=True, timeout=timeout, env=dict(os.environ))


def cli_ok(*args, **kw):
    """Run the CLI, assert success (exit code 0, no traceback); return the CompletedProcess."""
    r = cli(*args, **kw)
    assert r.returncode == 0 and 'Traceback' not in r.stderr, r.stdout + r.stderr
    return r


def stamp_ns(msg):
    """Return header.stamp in integer nanoseconds."""
    return msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec


class Ros:
    """A test-side rclpy node on its own context, spun explicitly."""

    def __init__(self, overrides=None):
        import rclpy
        from rclpy.context import Context
        from rclpy.executors import SingleThreadedExecutor
        self._rclpy = rclpy
        self.ctx = Context()
        rclpy.init(context=self.ctx)
        self.node = rclpy.create_node(f'test_{uuid.uuid4().hex[:8]}', context=self.ctx,
                                      parameter_overrides=overrides or [])
        self.ex = SingleThreadedExecutor(context=self.ctx)
        self.ex.add_node(self.node)
        self.extra = []

    def add_node(self, name, overrides=None):
        """Add a second node to the executor."""
        n = self._rclpy.create_node(name, context=self.ctx, parameter_overrides=overrides or [])
        self.ex.add_node(n)
        self.extra.append(n)
        return n

    def spin_for(self, seconds):
        """Spin for a while."""
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            self.ex.spin_once(timeout_sec=0.005)

    def spin_until(self, pred, timeout):
        """Spin until pred() is true or timeout; return pred()."""
        end = time.monotonic() + timeout
        while not pred() and time.monotonic() < end:
            self.ex.spin_once(timeout_sec=0.005)
        return pred()

    def collect(self, msg_type, topic, qos=None, raw=False):
        """Subscribe (qos: DEEP unless given) and return the list the messages are appended to."""
        out = []
        self.node.create_subscription(msg_type, topic, out.append,
                                      _deep() if qos is None else qos, raw=raw)
        return out

    def call(self, srv_type, name, request, timeout=10.0):
        """Call a service and return the response."""
        cli = self.node.create_client(srv_type, name)
        assert self.spin_until(cli.service_is_ready, timeout), f'{name} not available'
        fut = cli.call_async(request)
        assert self.spin_until(fut.done, timeout), f'{name} did not answer'
        return fut.result()

    def close(self):
        """Destroy everything."""
        self.ex.shutdown()
        for n in self.extra + [self.node]:
            n.destroy_node()
        self._rclpy.shutdown(context=self.ctx)


def start_node(run_exe, *params, record=False):
    """Start the node with -p params (record off unless asked)."""
    args = ['--ros-args']
    if not record:
        args += ['-p', 'record:=false']
    for p in params:
        args += ['-p', p]
    return run_exe('leadscrew_sim.node', *args)


def wait_states(ros, states, proc, n=1, timeout=30.0):
    """Wait until n axis/joint_states arrived (or the node died)."""
    ok = ros.spin_until(lambda: len(states) >= n or proc.proc.poll() is not None, timeout)
    assert ok and len(states) >= n, f'no axis/joint_states from the node:\n{proc.output()}'


def command_publisher(ros, topic='torque_command', msg_type=None, timeout=10.0):
    """Create a publisher (msg_type: std_msgs Float64 unless given); wait for the node."""
    if msg_type is None:
        from std_msgs.msg import Float64
        msg_type = Float64
    pub = ros.node.create_publisher(msg_type, topic, 10)
    assert ros.spin_until(lambda: pub.get_subscription_count() > 0, timeout)
    # Matching is one-sided: the node drops samples of a writer it has not yet
    # discovered itself, which on a loaded machine can trail this side's match.
    ros.spin_for(0.3)
    return pub


def publish_until(ros, pub, msg, pred, timeout=10.0, period=0.05):
    """Publish ``msg`` every ``period`` s [s] until ``pred()`` holds or ``timeout`` [s]."""
    end = time.monotonic() + timeout
    while not pred() and time.monotonic() < end:
        pub.publish(msg)
        ros.spin_for(period)
    return pred()


def param_msg(name, value):
    """Return an rcl_interfaces/Parameter message."""
    from rclpy.parameter import Parameter
    return Parameter(name, value=value).to_parameter_msg()
