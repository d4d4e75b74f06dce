"""
The real ros2_control stack around the node: build, environment, bring-up, and a stack-side client.

The stack (controller_manager 4.11.0, ros2_controllers 4.8.0,
topic_based_ros2_control 0.3.0) is built from ``../shared/ros2_control`` by
its ``setup.sh`` into ``$R2C`` (default ``~/.cache/leadscrew_sim/ros2_control``);
:func:`ensure_stack` runs it (it returns at once when up to date) and
:func:`stack_environment` gives the environment of its processes (``env.sh``
plus the suite's DDS domain, restricted to this host).

:class:`Axis` brings up one axis: the node from this venv in the namespace
:data:`NS`, ``ros2_control_node`` with the URDF of the package's xacro
(``ros2_control:=true``, the command interface asked for, the node's topics
named explicitly) on ``/robot_description`` (transient local), the
controllers through ``spawner``, a test-side rclpy node (helpers.Ros) and a
client under the stack's Python for what our venv has no messages for
(controller_manager_msgs, control_msgs). :meth:`Axis.stop` ends every process
group it started.

Run as a script under the stack's Python (``$R2C/venv/bin/python r2c.py``)
this module is that client: it reads one JSON request per line on stdin
(``list``, ``switch``, ``follow``, ``quit``) and answers one JSON line each.
It imports only the standard library at the top, and helpers (which does
the same), so that both interpreters load it.
"""
import json
import math
import os
from pathlib import Path
import queue
import signal
import subprocess
import sys
import threading
import time

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))   # test/: helpers
from helpers import REPO, SHARED, stamp_ns, wait_for  # noqa: E402

#: setup.sh of the shared stack (absent in a user's clone).
SETUP = SHARED / 'ros2_control' / 'setup.sh'
#: Namespace of the node under test, and the names its JointState pair gets (explicit).
NS = '/axis_under_test'
JOINT_STATES = f'{NS}/joint_states'
JOINT_COMMANDS = f'{NS}/joint_commands'
#: The node's JointState pair remapped to those names, from its default relative names
#: (axis/...) and the bare ones: remapping a name the node does not use is harmless, and
#: the tests do not depend on the node's defaults.
NODE_TOPIC_REMAPS = (('axis/joint_states', JOINT_STATES), ('axis/joint_commands', JOINT_COMMANDS),
                     ('joint_states', JOINT_STATES), ('joint_commands', JOINT_COMMANDS))
#: The controller_manager's node name.
CM = '/controller_manager'
#: setup.sh failures that mean "this machine lacks a prerequisite of the README": skip.
PREREQUISITE_FAILURES = (
    'not found (set PYTHON', 'is not Python 3.11', 'has no shared libpython',
    'no root/sudo to install them', 'no Python.h', 'cannot write to R2C')
#: pip's words for "no network" in a failed install (no access to PyPI: skip).
NO_NETWORK = ('NewConnectionError', 'Temporary failure in name resolution',
              'Network is unreachable')
#: Variables of the stack's env.sh that must not reach the node from our venv.
STACK_ONLY = ('LD_PRELOAD', 'R2C_LIBPYTHON', 'R2C')
#: Path lists from which the stack's entries are removed for the node.
PATH_LISTS = ('PATH', 'LD_LIBRARY_PATH', 'PYTHONPATH', 'AMENT_PREFIX_PATH',
              'CMAKE_PREFIX_PATH', 'COLCON_PREFIX_PATH')


def stack_prefix():
    """Return the stack's prefix: $R2C, else ~/.cache/leadscrew_sim/ros2_control."""
    return Path(os.environ.get('R2C') or Path.home() / '.cache/leadscrew_sim/ros2_control')


def _debian_12():
    try:
        text = Path('/etc/os-release').read_text()
    except OSError:
        return False
    fields = dict(line.split('=', 1) for line in text.splitlines() if '=' in line)
    return (fields.get('ID', '').strip('"') == 'debian'
            and fields.get('VERSION_ID', '').strip('"') == '12')


class StackUnavailable(Exception):
    """The machine lacks a prerequisite of the stack (the tests skip)."""


class StackBuildFailed(Exception):
    """setup.sh failed for another reason (the tests fail)."""


def ensure_stack(say, prefix=None):
    """
    Run setup.sh (an up-to-date stack returns at once); return the prefix.

    ``say(line)`` gets each progress line as it comes (a first build takes
    about 10 minutes). Raises StackUnavailable when the machine lacks a
    prerequisite the stack's README lists, StackBuildFailed with the last log
    lines for any other failure.
    """
    prefix = Path(prefix or stack_prefix())
    env = dict(os.environ, R2C=str(prefix), MAIN=str(REPO))
    proc = subprocess.Popen(['bash', str(SETUP)], cwd=REPO, env=env, stdin=subprocess.DEVNULL,
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    lines = []
    for line in proc.stdout:
        line = line.rstrip('\n')
        lines.append(line)
        say(line)
    rc = proc.wait()
    if rc == 0:
        return prefix
    reason = next((ln for ln in reversed(lines) if ln.startswith('setup.sh: FAILED')),
                  f'setup.sh exited with {rc}')
    log = reason.rsplit('see ', 1)[-1].split(' ')[0].rstrip(')') if 'see ' in reason else ''
    text = Path(log).read_text(errors='replace') if log and Path(log).is_file() else ''
    if (any(m in reason for m in PREREQUISITE_FAILURES)
            or (reason.startswith('setup.sh: FAILED (init)') and reason.endswith(' not found'))):
        raise StackUnavailable(reason)       # no Python 3.11 (PYTHON=... names none)
    if 'pip install' in reason and any(m in text for m in NO_NETWORK):
        raise StackUnavailable(f'{reason} (no access to PyPI)')
    if not _debian_12():
        raise StackUnavailable(f'{reason} (the stack is built for Debian 12, this is not)')
    tail = '\n'.join(text.splitlines()[-30:])
    raise StackBuildFailed('\n'.join(lines[-15:]) + (f'\n--- last lines of {log}:\n{tail}'
                                                     if tail else ''))


def _without(value, prefix):
    """Return the path list ``value`` without the entries inside ``prefix``."""
    keep = [p for p in value.split(os.pathsep)
            if p and not (p == str(prefix) or p.startswith(str(prefix) + os.sep))]
    return os.pathsep.join(keep)


def _ros_settings(env):
    env['ROS_DOMAIN_ID'] = os.environ['ROS_DOMAIN_ID']
    env['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
    env.pop('ROS_LOCALHOST_ONLY', None)
    env['ROS_LOG_DIR'] = os.environ.get('ROS_LOG_DIR', str(REPO / '.ros_log'))
    return env


def stack_environment(prefix):
    """
    Return the environment of the stack's processes: ``. $R2C/env.sh`` on a clean base.

    The base is this process's environment without our venv (its bin on
    PATH, its AMENT_PREFIX_PATH, PYTHONPATH) and without a previously sourced
    stack; the suite's ROS_DOMAIN_ID and a LOCALHOST discovery range are set
    after sourcing.
    """
    base = {k: v for k, v in os.environ.items()
            if k not in ('AMENT_PREFIX_PATH', 'CMAKE_PREFIX_PATH', 'PYTHONPATH', 'PYTHONHOME',
                         'VIRTUAL_ENV', 'LD_PRELOAD', 'LD_LIBRARY_PATH', 'COLCON_PREFIX_PATH')}
    base['PATH'] = _without(_without(os.environ.get('PATH', '/usr/bin:/bin'), sys.prefix),
                            prefix)
    base['R2C'] = str(prefix)
    out = subprocess.run(['bash', '-c', '. "$R2C/env.sh" && env -0'], env=base,
                         capture_output=True, timeout=60)
    if out.returncode != 0:
        raise StackBuildFailed(f'sourcing {prefix}/env.sh failed: {out.stderr.decode()[-2000:]}')
    env = dict(item.split('=', 1) for item in out.stdout.decode().split('\0') if '=' in item)
    env.pop('_', None)
    return _ros_settings(env)


def node_environment(prefix):
    """Return the environment of our node: this process's, without anything of the stack."""
    env = {k: v for k, v in os.environ.items() if k not in STACK_ONLY}
    for key in PATH_LISTS:
        if key in env:
            env[key] = _without(env[key], prefix)
            if not env[key]:
                del env[key]
    return _ros_settings(env)


class Group:
    """A process started in a session (process group) of its own, its output in a log file."""

    def __init__(self, argv, log_path, env, pipe=False):
        self.argv = [str(a) for a in argv]
        self.log_path = Path(log_path)
        self._log = open(log_path, 'wb')
        self.proc = subprocess.Popen(
            self.argv, env=env, start_new_session=True,
            stdin=subprocess.PIPE if pipe else subprocess.DEVNULL,
            stdout=subprocess.PIPE if pipe else self._log,
            stderr=self._log if pipe else subprocess.STDOUT)
        self.pgid = self.proc.pid

    def output(self, last=None):
        """Return what the process printed (its last ``last`` lines)."""
        self._log.flush()
        text = self.log_path.read_text(errors='replace')
        return text if last is None else '\n'.join(text.splitlines()[-last:])

    def group_alive(self):
        """Return whether any process of the group is left."""
        try:
            os.killpg(self.pgid, 0)
        except ProcessLookupError:
            return False
        except PermissionError:
            return True
        return True

    def _signal(self, sig):
        try:
            os.killpg(self.pgid, sig)
        except ProcessLookupError:
            pass

    def stop(self, timeout=10.0):
        """SIGINT to the group; SIGKILL what is left after ``timeout`` s. Return the exit code."""
        if self.proc.poll() is None:
            self._signal(signal.SIGINT)
            try:
                self.proc.wait(timeout=timeout)
            except subprocess.TimeoutExpired:
                self._signal(signal.SIGKILL)
                self.proc.wait(timeout=10)
        if self.group_alive():                 # children the leader left behind
            self._signal(signal.SIGKILL)
            wait_for(lambda: not self.group_alive(), 5.0)
        self._log.close()
        return self.proc.returncode


class StackClient(Group):
    """This module run as a JSON-lines client under the stack's Python (its own group)."""

    def __init__(self, prefix, env, log_path):
        super().__init__([Path(prefix) / 'venv/bin/python', __file__], log_path, env, pipe=True)
        self._lines = queue.Queue()
        threading.Thread(target=self._read, daemon=True).start()
        self.ready = None

    def _read(self):
        for line in self.proc.stdout:
            self._lines.put(line.decode(errors='replace'))
        self._lines.put(None)

    def _reply(self, timeout):
        end = time.monotonic() + timeout
        while True:
            try:
                line = self._lines.get(timeout=max(0.0, end - time.monotonic()))
            except queue.Empty:
                raise AssertionError(f'the stack client did not answer within {timeout} s:\n'
                                     f'{self.output(30)}') from None
            if line is None:
                raise AssertionError(f'the stack client exited:\n{self.output(30)}')
            if line.startswith('{'):
                return json.loads(line)

    def wait_ready(self, timeout=30.0):
        """Wait for the client's ready line."""
        if self.ready is None:
            self.ready = self._reply(timeout)
        return self.ready

    def request(self, op, timeout=30.0, **args):
        """Send one request; return its JSON answer (an AssertionError on an 'error' answer)."""
        self.wait_ready()
        self.proc.stdin.write((json.dumps(dict(args, op=op)) + '\n').encode())
        self.proc.stdin.flush()
        answer = self._reply(timeout + 10.0)
        assert 'error' not in answer, f'{op}: {answer["error"]}\n{self.output(30)}'
        return answer

    def stop(self, timeout=5.0):
        """Ask the client to quit, then end its group."""
        if self.proc.poll() is None:
            try:
                self.proc.stdin.write(b'{"op": "quit"}\n')
                self.proc.stdin.flush()
                self.proc.wait(timeout=timeout)
            except (OSError, subprocess.TimeoutExpired):
                pass
        return super().stop(timeout)


def controllers_yaml(command_interface, update_rate, joint):
    """
    Return the controller_manager's parameter file (text) for one axis.

    Declares joint_state_broadcaster, ``<interface>_controller``
    (forward_command_controller on the one command interface) and, for the
    position interface, joint_trajectory_controller with the tolerances of
    the trajectory tests: 1 mm along the path, 0.1 mm at the goal, 1 s to
    get there. JTC 4.8.0 checks only these (its parameters): it ignores the
    tolerances of a FollowJointTrajectory goal.
    """
    fwd = f'{command_interface}_controller'
    # position_velocity: the forward controller commands the position; the trajectory
    # controller commands both (its velocity the node's position-loop feed-forward)
    fwd_interface = 'position' if command_interface == 'position_velocity' else command_interface
    jtc = command_interface in ('position', 'position_velocity')
    jtc_interfaces = '[position, velocity]' if command_interface == 'position_velocity' \
        else '[position]'
    text = f"""controller_manager:
  ros__parameters:
    update_rate: {int(update_rate)}
    joint_state_broadcaster:
      type: joint_state_broadcaster/JointStateBroadcaster
    {fwd}:
      type: forward_command_controller/ForwardCommandController
"""
    if jtc:
        text += """    joint_trajectory_controller:
      type: joint_trajectory_controller/JointTrajectoryController
"""
    text += f"""
{fwd}:
  ros__parameters:
    joints: [{joint}]
    interface_name: {fwd_interface}
"""
    if jtc:
        text += f"""
joint_trajectory_controller:
  ros__parameters:
    joints: [{joint}]
    command_interfaces: {jtc_interfaces}
    state_interfaces: [position, velocity]
    constraints:
      stopped_velocity_tolerance: {STOPPED_VELOCITY}
      goal_time: {GOAL_TIME}
      {joint}:
        trajectory: {PATH_TOLERANCE}
        goal: {GOAL_TOLERANCE}
"""
    return text


#: The trajectory tests' tolerances: path 1 mm, goal 0.1 mm [m], 1 s to reach the goal,
#: and at the goal the nut below 2 mm/s (the node holds it at rest there).
PATH_TOLERANCE = 0.001
GOAL_TOLERANCE = 0.0001
GOAL_TIME = 1.0
STOPPED_VELOCITY = 0.002


class Axis:
    """
    The node behind the real controller_manager, with the controllers spawned.

    Parameters
    ----------
    prefix : Path
        The stack's prefix ($R2C).
    workdir : Path
        Where the parameter files and the logs go (a test's tmp_path).
    command_interface : str
        ``position``, ``velocity`` or ``effort`` (the xacro argument, and the
        node's ``joint_command_mode``).
    update_rate : int
        The controller_manager's update rate [Hz].
    node_params : sequence of str
        Extra ``name:=value`` parameters of the node.
    active, inactive : sequence of str
        Controllers to spawn active, then inactive.
    stroke : float
        The stroke is [-stroke, stroke] [m] (node and URDF).

    """

    def __init__(self, prefix, workdir, command_interface='position', update_rate=100,
                 node_params=(), active=(), inactive=(), stroke=0.05, defaults=False,
                 xacro=None):
        self.prefix, self.workdir = Path(prefix), Path(workdir)
        self.command_interface, self.update_rate = command_interface, int(update_rate)
        self.joint = 'screw_joint' if command_interface == 'effort' else 'nut_joint'
        mode = 'position' if command_interface == 'position_velocity' else command_interface
        self.node_params = [f'joint_command_mode:={mode}', 'record:=false',
                            f'stroke_min:={-stroke}', f'stroke_max:={stroke}', *node_params]
        #: defaults: the bring-up a user gets by default: the node in the root namespace with
        #: its own topic names, the xacro's default topic names (the node's there).
        self.defaults = defaults
        self.xacro = dict(xacro or {})
        self.states_topic = '/axis/joint_states' if defaults else JOINT_STATES
        self.active, self.inactive = list(active), list(inactive)
        self.stroke = stroke
        self.procs = []
        self.ros = None
        self.client = None
        self.node = self.cm = None
        #: (receipt time [ns, system clock], JointState) of the node's joint_states.
        self.received = []
        #: JointState messages of the joint_state_broadcaster (/joint_states).
        self.broadcast = []
        self._pubs = {}
        #: Stamp lags [ms] of the joint_states received in 0.5 s of continuous spinning.
        self.lag_window = []

    # ----------------------------------------------------------------- bring-up
    def urdf(self):
        """Return the URDF of the package's xacro with this axis's ros2_control block."""
        from leadscrew_sim.io.description import render_urdf
        args = {'ros2_control': 'true', 'command_interface': self.command_interface,
                'stroke_min': -self.stroke, 'stroke_max': self.stroke, **self.xacro}
        if not self.defaults:
            args.update(joint_states_topic=JOINT_STATES, joint_commands_topic=JOINT_COMMANDS)
        return render_urdf(args)

    def _start(self, name, argv, env, **kw):
        p = Group(argv, self.workdir / f'{name}.log', env, **kw)
        self.procs.append(p)
        return p

    def start(self):
        """Bring everything up; return self once the controllers are spawned and states flow."""
        import helpers
        from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
        from sensor_msgs.msg import JointState
        from std_msgs.msg import String
        senv, nenv = stack_environment(self.prefix), node_environment(self.prefix)
        params = self.workdir / 'controllers.yaml'
        params.write_text(controllers_yaml(self.command_interface, self.update_rate, self.joint))
        urdf = self.urdf()
        (self.workdir / 'axis.urdf').write_text(urdf)
        # The node is the slowest to come up (numba kernel load): first.
        argv = [sys.executable, '-m', 'leadscrew_sim.node', '--ros-args']
        if not self.defaults:
            argv += ['-r', f'__ns:={NS}']
            for name, topic in NODE_TOPIC_REMAPS:
                argv += ['-r', f'{name}:={topic}']
        for p in self.node_params:
            argv += ['-p', p]
        self.node = self._start('node', argv, nenv)
        self.client = StackClient(self.prefix, senv, self.workdir / 'client.log')
        self.procs.append(self.client)
        self.ros = helpers.Ros()
        latched = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                             durability=DurabilityPolicy.TRANSIENT_LOCAL)
        self._pubs['description'] = self.ros.node.create_publisher(
            String, '/robot_description', latched)
        self._pubs['description'].publish(String(data=urdf))
        self.ros.node.create_subscription(
            JointState, self.states_topic,
            lambda m: self.received.append((time.time_ns(), m)), helpers.DEEP)
        self.ros.node.create_subscription(JointState, '/joint_states', self.broadcast.append,
                                          helpers.DEEP)
        # The hardware acts as soon as ros2_control_node activates it (without an initial_value
        # it commands 0 at once): this process sees the node's states first, or it may miss
        # the start of what the test looks at.
        self.wait_states()
        lib = self.prefix / 'install/lib/controller_manager'
        self.cm = self._start('ros2_control_node', [
            lib / 'ros2_control_node', '--ros-args', '--params-file', params,
            '-r', '~/robot_description:=/robot_description'], senv)
        spawns = []
        if self.active:
            spawns.append([*self.active])
        if self.inactive:
            spawns.append([*self.inactive, '--inactive'])
        for i, args in enumerate(spawns):
            sp = self._start(f'spawner-{i}', [lib / 'spawner', *args, '-c', CM,
                                              '--controller-manager-timeout', '60'], senv)
            # Spin while the spawner works: the node's states queue up otherwise.
            ok = self.ros.spin_until(lambda: sp.proc.poll() is not None, 90.0)
            assert ok and sp.proc.returncode == 0, (
                f'spawner {" ".join(args)} failed ({sp.proc.returncode}):\n{sp.output(20)}\n'
                f'--- ros2_control_node:\n{self.cm.output(30)}')
        # The loop is closed once the broadcaster republishes what the node reports.
        if 'joint_state_broadcaster' in self.active:
            ok = self.ros.spin_until(lambda: self.broadcast_position() is not None, 20.0)
            assert ok, f'no /joint_states from the broadcaster:\n{self.cm.output(30)}'
        self.client.wait_ready()
        # The stamps against the system clock, over a window of continuous spinning (messages
        # that queued while the test did not spin would add that pause to their lag).
        self.spin(0.1)
        first = len(self.received)
        self.spin(0.5)
        self.lag_window = self.stamp_lags_ms(first)
        return self

    def wait_states(self, timeout=60.0):
        """Wait for the node's first joint_states (it takes seconds to load its kernel)."""
        ok = self.ros.spin_until(lambda: self.received or self.node.proc.poll() is not None,
                                 timeout)
        assert ok and self.received, f'no joint_states from the node:\n{self.node.output()}'

    def stop(self):
        """End every process group, close the test-side node; return the groups still alive."""
        for p in reversed(self.procs):
            p.stop()
        if self.ros is not None:
            self.ros.close()
            self.ros = None
        return [p.argv[0] for p in self.procs if p.group_alive()]

    # ----------------------------------------------------------------- state
    def index(self, msg, joint=None):
        """Return the index of ``joint`` (default the commanded one) in a JointState."""
        return list(msg.name).index(joint or self.joint)

    def latest(self):
        """Return the node's latest joint_states."""
        return self.received[-1][1]

    def nut(self):
        """Return the nut position [m] of the node's latest joint_states."""
        m = self.latest()
        return m.position[self.index(m, 'nut_joint')]

    def nut_velocity(self):
        """Return the nut velocity [m/s] of the node's latest joint_states."""
        m = self.latest()
        return m.velocity[self.index(m, 'nut_joint')]

    def broadcast_position(self):
        """Return the commanded joint's position on the broadcaster's /joint_states, or None."""
        for m in reversed(self.broadcast[-5:]):
            if self.joint in m.name:
                return m.position[self.index(m)]
        return None

    def spin(self, seconds):
        """Spin the test-side node (collect states) for a while."""
        self.ros.spin_for(seconds)

    def spin_until(self, pred, timeout):
        """Spin until pred() holds or timeout; return pred()."""
        return self.ros.spin_until(pred, timeout)

    def since(self, t_ns):
        """Return the node's joint_states with a stamp at or after ``t_ns``."""
        return [m for _r, m in self.received if stamp_ns(m) >= t_ns]

    def stamp_lags_ms(self, skip=0):
        """Return receipt (system clock) less header stamp [ms] of the node's joint_states."""
        return [(r - stamp_ns(m)) / 1e6 for r, m in self.received[skip:]]

    # ----------------------------------------------------------------- commands
    def command(self, value, controller=None, timeout=10.0):
        """
        Publish ``[value]`` to ``<controller>/commands`` (default the forward controller).

        Waits for the controller's subscription first. The controller keeps
        the last command and writes it every cycle, so one message is enough
        once matched; publishing it again is harmless.
        """
        from std_msgs.msg import Float64MultiArray
        topic = f'/{controller or self.command_interface + "_controller"}/commands'
        pub = self._pubs.get(topic)
        if pub is None:
            pub = self._pubs[topic] = self.ros.node.create_publisher(
                Float64MultiArray, topic, 10)
            assert self.spin_until(lambda: pub.get_subscription_count() > 0, timeout), \
                f'nobody subscribes {topic}'
            # Matching is one-sided: the controller may not have matched us yet.
            self.spin(0.3)
        for _ in range(3):
            pub.publish(Float64MultiArray(data=[float(value)]))
            self.spin(0.01)

    def controllers(self):
        """Return {name: (state, type, claimed interfaces)} of list_controllers."""
        answer = self.client.request('list', cm=CM)
        return {c['name']: (c['state'], c['type'], c['claimed']) for c in answer['controllers']}

    def switch(self, activate=(), deactivate=()):
        """Call switch_controller (STRICT); return its ``ok``."""
        return self.client.request('switch', cm=CM, activate=list(activate),
                                   deactivate=list(deactivate))['ok']

    def follow(self, points, path_tolerance=PATH_TOLERANCE, goal_tolerance=GOAL_TOLERANCE,
               goal_time_tolerance=GOAL_TIME, timeout=30.0):
        """
        Send a FollowJointTrajectory goal to joint_trajectory_controller; return the answer.

        ``points`` are (time_from_start [s], position [m]) of the nut joint,
        the last one at rest. The answer holds ``accepted``, ``status``,
        ``error_code``, ``error_string`` and ``max_feedback_error`` [m] (the
        largest position error of the controller's feedback). Spins the
        test-side node meanwhile, so that the node's states are collected.
        """
        box = {}

        def call():
            try:
                box['answer'] = self.client.request(
                    'follow', timeout=timeout, joint=self.joint, points=points,
                    path_tolerance=path_tolerance, goal_tolerance=goal_tolerance,
                    goal_time_tolerance=goal_time_tolerance)
            except AssertionError as exc:
                box['error'] = exc
        t = threading.Thread(target=call, daemon=True)
        t.start()
        self.spin_until(lambda: not t.is_alive(), timeout + 20.0)
        t.join(1.0)
        if 'error' in box:
            raise box['error']
        assert 'answer' in box, 'the goal did not finish'
        return box['answer']


# --------------------------------------------------------------------------- stack side
def _serve():   # pragma: no cover - runs under the stack's Python
    """Answer JSON requests on stdin, with the stack's rclpy and messages."""
    import rclpy
    from rclpy.action import ActionClient
    from builtin_interfaces.msg import Duration
    from control_msgs.action import FollowJointTrajectory
    from control_msgs.msg import JointTolerance
    from controller_manager_msgs.srv import ListControllers, SwitchController
    from trajectory_msgs.msg import JointTrajectoryPoint

    rclpy.init()
    node = rclpy.create_node(f'r2c_test_client_{os.getpid()}')
    clients = {}

    def out(obj):
        sys.stdout.write(json.dumps(obj) + '\n')
        sys.stdout.flush()

    def service(srv_type, name, request, timeout):
        cli = clients.get(name)
        if cli is None:
            cli = clients[name] = node.create_client(srv_type, name)
        if not cli.wait_for_service(timeout_sec=timeout):
            raise RuntimeError(f'{name} not available')
        fut = cli.call_async(request)
        rclpy.spin_until_future_complete(node, fut, timeout_sec=timeout)
        if fut.result() is None:
            raise RuntimeError(f'{name} did not answer')
        return fut.result()

    def duration(seconds):
        ns = int(round(seconds * 1e9))
        return Duration(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)

    def op_list(req):
        res = service(ListControllers, f'{req["cm"]}/list_controllers',
                      ListControllers.Request(), req.get('timeout', 10.0))
        return {'controllers': [{'name': c.name, 'state': c.state, 'type': c.type,
                                 'claimed': list(c.claimed_interfaces)}
                                for c in res.controller]}

    def op_switch(req):
        r = SwitchController.Request(activate_controllers=req['activate'],
                                     deactivate_controllers=req['deactivate'],
                                     strictness=SwitchController.Request.STRICT,
                                     timeout=duration(5.0))
        return {'ok': bool(service(SwitchController, f'{req["cm"]}/switch_controller', r,
                                   req.get('timeout', 10.0)).ok)}

    def op_follow(req):
        timeout = req.get('timeout', 30.0)
        name = '/joint_trajectory_controller/follow_joint_trajectory'
        act = clients.get(name)
        if act is None:
            act = clients[name] = ActionClient(node, FollowJointTrajectory, name)
        if not act.wait_for_server(timeout_sec=10.0):
            raise RuntimeError(f'{name} not available')
        goal = FollowJointTrajectory.Goal()
        joint = req['joint']
        goal.trajectory.joint_names = [joint]
        pts = req['points']
        for i, (t, x) in enumerate(pts):
            p = JointTrajectoryPoint(positions=[float(x)], time_from_start=duration(t))
            if i == len(pts) - 1:
                p.velocities = [0.0]
            goal.trajectory.points.append(p)
        goal.path_tolerance = [JointTolerance(name=joint, position=req['path_tolerance'])]
        goal.goal_tolerance = [JointTolerance(name=joint, position=req['goal_tolerance'])]
        goal.goal_time_tolerance = duration(req['goal_time_tolerance'])
        worst = [0.0]
        samples = []

        def feedback(msg):
            err = msg.feedback.error.positions
            if err:
                worst[0] = max(worst[0], abs(err[0]))
                vel = msg.feedback.desired.velocities
                samples.append((float(err[0]), float(vel[0]) if vel else math.nan))
        sent = time.time_ns()
        fut = act.send_goal_async(goal, feedback_callback=feedback)
        rclpy.spin_until_future_complete(node, fut, timeout_sec=10.0)
        handle = fut.result()
        if handle is None or not handle.accepted:
            return {'accepted': False}
        res_fut = handle.get_result_async()
        rclpy.spin_until_future_complete(node, res_fut, timeout_sec=timeout)
        res = res_fut.result()
        if res is None:
            return {'accepted': True, 'status': None, 'error_code': None,
                    'error_string': f'no result within {timeout} s'}
        return {'accepted': True, 'status': res.status, 'error_code': res.result.error_code,
                'error_string': res.result.error_string, 'max_feedback_error': worst[0],
                'feedback': samples,
                'sent_ns': sent, 'done_ns': time.time_ns()}

    ops = {'list': op_list, 'switch': op_switch, 'follow': op_follow}
    out({'ready': True})
    for line in sys.stdin:
        if not line.strip():
            continue
        req = json.loads(line)
        if req['op'] == 'quit':
            break
        try:
            out(ops[req['op']](req))
        except Exception as exc:  # noqa: B902 - every failure goes back to the test
            out({'error': f'{type(exc).__name__}: {exc}'})
    node.destroy_node()
    rclpy.try_shutdown()


if __name__ == '__main__':
    _serve()
