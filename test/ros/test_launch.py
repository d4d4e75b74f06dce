"""
The launch files as a ROS user runs them: `ros2 launch leadscrew_sim ...`, then Ctrl-C.

Needs the real ROS 2 Jazzy tools of ../shared/ros2-tools (skips without them).
They go into a venv of their own, <venv>/ros2-tools-venv (install.sh, with
the test venv's pip through a .pth file), and run on the test venv's python
with their site-packages on PYTHONPATH, as after sourcing a ROS workspace:
installed into the test venv itself, launch_testing's pytest plugin (written
for an older pytest) stops every later pytest run of that venv at start-up,
and the ROS wheels find their shared libraries only for their own venv
(ros_wheels_bootstrapper uses sys.prefix). The package is
installed into a temporary prefix the way colcon's ament_python build does
(setup.py install, lib/leadscrew_sim, the ament index marker); that prefix and
the test venv form AMENT_PREFIX_PATH. Oracles: the topics and joint names of
interfaces.md, parameter values read from the YAML files, the URDF limits
from the preset, and ros2 launch's own exit code and process log lines.
"""
import fcntl
import io
import json
import math
import os
import re
from pathlib import Path
import shutil
import signal
import subprocess
import sys
import sysconfig
import textwrap
import time

from helpers import REPO, SHARED
import pytest
import yaml
import yourdfpy

INSTALL_SH = SHARED / 'ros2-tools' / 'install.sh'
TOOLS_VENV = Path(sys.prefix) / 'ros2-tools-venv'
DOMAIN_ID = 100 + os.getpid() % 100

pytestmark = [
    pytest.mark.slow,
    pytest.mark.skipif(not INSTALL_SH.is_file(),
                       reason='../shared/ros2-tools is absent; the launch tests need it'),
]


@pytest.fixture(scope='session')
def ros2():
    """Path of the `ros2` command of the real Jazzy tools, installed once per venv."""
    exe = TOOLS_VENV / 'bin' / 'ros2'
    with open(Path(sys.prefix) / '.ros2-tools-venv.lock', 'w') as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)        # one installer at a time
        tools_py = TOOLS_VENV / 'bin' / 'python'
        if not tools_py.is_file():
            # No pip of its own: install.sh runs the test venv's pip and setuptools.
            subprocess.run([sys.executable, '-m', 'venv', '--clear', '--without-pip',
                            str(TOOLS_VENV)], check=True)
            site = subprocess.run(
                [str(tools_py), '-c', 'import sysconfig; print(sysconfig.get_path("purelib"))'],
                check=True, capture_output=True, text=True).stdout.strip()
            here = sysconfig.get_path('purelib')
            # addsitedir also runs the .pth files of the test venv (ros_wheels_bootstrapper).
            Path(site, 'test_venv_overlay.pth').write_text(
                f'import site; site.addsitedir({here!r})\n')
        # Idempotent: returns at once when this version of the tools is installed.
        res = subprocess.run(['bash', str(INSTALL_SH), str(TOOLS_VENV)],
                             capture_output=True, text=True)
        assert res.returncode == 0 and exe.is_file(), res.stdout + res.stderr
    return exe


def tools_site_packages():
    return Path(subprocess.run(
        [str(TOOLS_VENV / 'bin' / 'python'), '-c',
         'import sysconfig; print(sysconfig.get_path("purelib"))'],
        check=True, capture_output=True, text=True).stdout.strip())


@pytest.fixture(scope='module')
def prefix(tmp_path_factory):
    """Install the package into a fresh prefix as colcon's ament_python task does."""
    tmp = tmp_path_factory.mktemp('ws')
    src = tmp / 'src'
    shutil.copytree(REPO, src, ignore=shutil.ignore_patterns(
        '.venv', '.git', 'build', 'install', 'log', 'runs', '.ros_log', '*.egg-info',
        '__pycache__', '.hypothesis'))
    (tmp / 'build').mkdir()
    res = subprocess.run(
        [sys.executable, 'setup.py', 'egg_info', '--egg-base', str(tmp / 'build'),
         'build', '--build-base', str(tmp / 'build' / 'build'),
         'install', '--prefix', str(tmp / 'install'), '--record', str(tmp / 'record.txt'),
         '--single-version-externally-managed'],
        cwd=src, capture_output=True, text=True)
    assert res.returncode == 0, res.stdout + res.stderr
    install = tmp / 'install'
    for rel in ('share/ament_index/resource_index/packages/leadscrew_sim',
                'share/leadscrew_sim/launch/leadscrew_sim.launch.py',
                'share/leadscrew_sim/launch/gantry.launch.py',
                'share/leadscrew_sim/urdf/leadscrew_axis.urdf.xacro',
                'lib/leadscrew_sim/leadscrew_sim_node'):
        assert (install / rel).is_file(), rel
    return install


def site_packages(prefix):
    return prefix / 'lib' / f'python{sys.version_info[0]}.{sys.version_info[1]}' / \
        'site-packages'


def launch_env(*prefixes):
    """Environment of a shell that sourced the install prefixes, isolated to this host."""
    env = dict(os.environ)
    env['AMENT_PREFIX_PATH'] = os.pathsep.join([*map(str, prefixes), sys.prefix])
    # The tools run on the test venv's interpreter with their site-packages on
    # PYTHONPATH (the ROS wheels set up their libraries for sys.prefix only).
    env['PYTHONPATH'] = os.pathsep.join(
        [*(str(site_packages(p)) for p in prefixes), str(tools_site_packages())])
    env['ROS_DOMAIN_ID'] = str(DOMAIN_ID)
    env['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
    env.pop('ROS_LOCALHOST_ONLY', None)
    env['PYTHONUNBUFFERED'] = '1'
    # As in a shell with the venv activated (xacro is a script in its bin/).
    env['PATH'] = os.pathsep.join([str(Path(sys.prefix) / 'bin'), env.get('PATH', '')])
    return env


class Launch:
    """`ros2 launch` in its own process group, as a terminal runs it."""

    def __init__(self, ros2, args, env, log_path):
        self.log_path = log_path
        self._log = open(log_path, 'wb')
        self.proc = subprocess.Popen([sys.executable, str(ros2), 'launch', 'leadscrew_sim',
                                      *args], env=env,
                                     stdout=self._log, stderr=subprocess.STDOUT,
                                     start_new_session=True)

    def output(self):
        self._log.flush()
        return Path(self.log_path).read_text(errors='replace')

    def ctrl_c(self, timeout=40.0):
        """SIGINT to the whole process group (what Ctrl-C does); return the exit code."""
        os.killpg(self.proc.pid, signal.SIGINT)
        try:
            return self.proc.wait(timeout=timeout)
        except subprocess.TimeoutExpired:
            return None

    def kill(self):
        if self.proc.poll() is None:
            try:
                os.killpg(self.proc.pid, signal.SIGKILL)
            except ProcessLookupError:
                pass
            self.proc.wait(timeout=10)
        else:                                    # stragglers of an exited launch
            try:
                os.killpg(self.proc.pid, signal.SIGKILL)
            except ProcessLookupError:
                pass
        self._log.close()


@pytest.fixture
def launch(ros2, tmp_path):
    """Start `ros2 launch leadscrew_sim <args>`; everything is killed after the test."""
    started = []

    def start(args, env):
        proc = Launch(ros2, args, env, tmp_path / f'launch-{len(started)}.log')
        started.append(proc)
        return proc

    yield start
    for proc in started:
        proc.kill()


@pytest.fixture
def probe():
    """Yield an rclpy node in the launch's domain (own context) with a spin-until helper."""
    import rclpy
    from rclpy.context import Context
    from rclpy.executors import SingleThreadedExecutor
    context = Context()
    rclpy.init(context=context, domain_id=DOMAIN_ID)
    node = rclpy.create_node('launch_test_probe', context=context)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)

    def spin_until(predicate, timeout, alive=None):
        end = time.monotonic() + timeout
        while not predicate() and time.monotonic() < end:
            if alive is not None and not alive():
                break
            executor.spin_once(timeout_sec=0.05)
        return predicate()

    node.spin_until = spin_until
    yield node
    executor.shutdown()
    node.destroy_node()
    rclpy.shutdown(context=context)


def first_messages(node, topics, launch, timeout=90.0):
    """Subscribe to sensor_msgs/JointState topics; return {topic: first message}."""
    from sensor_msgs.msg import JointState
    got = {}
    subs = [node.create_subscription(JointState, t, lambda m, t=t: got.setdefault(t, m), 10)
            for t in topics]
    node.spin_until(lambda: len(got) == len(topics), timeout,
                    alive=lambda: launch.proc.poll() is None)
    for s in subs:
        node.destroy_subscription(s)
    return got


def get_parameter(node, fqn, name, timeout=20.0):
    """Value of one parameter of a node through its get_parameters service."""
    from rcl_interfaces.srv import GetParameters
    from rclpy.parameter import parameter_value_to_python
    client = node.create_client(GetParameters, f'{fqn}/get_parameters')
    assert node.spin_until(client.service_is_ready, timeout), f'{fqn}/get_parameters'
    future = client.call_async(GetParameters.Request(names=[name]))
    assert node.spin_until(future.done, timeout)
    node.destroy_client(client)
    (value,) = future.result().values
    return parameter_value_to_python(value)


def ros_parameters(path):
    with open(path) as fh:
        doc = yaml.safe_load(fh)
    (section,) = [v for v in doc.values() if isinstance(v, dict) and 'ros__parameters' in v]
    return section['ros__parameters']


def assert_clean_exit(launch, rc, processes):
    out = launch.output()
    assert rc == 0, f'ros2 launch exit code {rc} after SIGINT:\n{out}'
    assert 'process has died' not in out, out
    assert out.count('process has finished cleanly') == processes, out


def test_single_axis_in_a_namespace(launch, probe, prefix, tmp_path):
    params_file = prefix / 'share/leadscrew_sim/config/stick_slip.yaml'
    runs = tmp_path / 'runs'
    proc = launch(['leadscrew_sim.launch.py', 'namespace:=ax1', f'params_file:={params_file}',
                   f'record_dir:={runs}'], launch_env(prefix))
    got = first_messages(probe, ['/ax1/axis/joint_states'], proc)
    assert '/ax1/axis/joint_states' in got, proc.output()
    msg = got['/ax1/axis/joint_states']
    assert list(msg.name) == ['screw_joint', 'nut_joint']
    assert all(math.isfinite(v) for v in (*msg.position, *msg.velocity, *msg.effort))
    # The file's values reach the namespaced node (its key is /**).
    expected = ros_parameters(params_file)
    for name in ('payload_mass', 'mu_s', 'coupling_stiffness'):
        assert get_parameter(probe, '/ax1/leadscrew_sim_node', name) == \
            pytest.approx(expected[name]), name
    # ... and the physics: at rest the thread carries the weight (m_n + m_p) g.
    weight = (expected['nut_mass'] + expected['payload_mass']) * 9.80665
    assert abs(msg.effort[1]) == pytest.approx(weight, rel=0.02)
    rc = proc.ctrl_c()
    assert_clean_exit(proc, rc, processes=1)
    assert sorted(runs.glob('*.mcap')), 'no recording in record_dir'


def test_gantry_two_axes(launch, probe, prefix, tmp_path):
    runs = tmp_path / 'runs'
    proc = launch(['gantry.launch.py', f'record_dir:={runs}'], launch_env(prefix))
    topics = ['/x_axis/axis/joint_states', '/y_axis/axis/joint_states']
    got = first_messages(probe, topics, proc)
    assert sorted(got) == topics, proc.output()
    assert list(got['/x_axis/axis/joint_states'].name) == ['x_screw_joint', 'x_nut_joint']
    assert list(got['/y_axis/axis/joint_states'].name) == ['y_screw_joint', 'y_nut_joint']
    assert get_parameter(probe, '/x_axis/leadscrew_sim_node', 'joint_prefix') == 'x_'
    rc = proc.ctrl_c()
    assert_clean_exit(proc, rc, processes=2)
    for axis in ('x_axis', 'y_axis'):
        assert sorted((runs / axis).glob('*.mcap')), axis


FAKE_RSP = '''\
#!{python}
"""Stand-in robot_state_publisher: saves its robot_description and arguments."""
import json, os, signal, sys, time
import yaml

args = sys.argv[1:]
params = {{}}
for i, a in enumerate(args):
    if a == '--params-file':
        with open(args[i + 1]) as fh:
            for section in (yaml.safe_load(fh) or {{}}).values():
                params.update(section.get('ros__parameters', {{}}))
stop = []
signal.signal(signal.SIGINT, lambda *_: stop.append(1))
signal.signal(signal.SIGTERM, lambda *_: stop.append(1))
out = os.environ['FAKE_RSP_OUT']
with open(out + '.part', 'w') as fh:
    json.dump({{'argv': args, 'parameters': params}}, fh)
os.replace(out + '.part', out)      # the test reads it whole or not at all
while not stop:
    time.sleep(0.05)
# Ctrl-C reaches it twice (the group's SIGINT and the one launch forwards): the second can
# land while the interpreter shuts down, with the default handler back, and kill it with
# -2; the real robot_state_publisher takes both, so the stand-in leaves without shutting down.
os._exit(0)
'''


@pytest.fixture
def fake_rsp_prefix(tmp_path):
    """Make a prefix whose robot_state_publisher executable records its input."""
    # The real one is C++ and not on PyPI; what the launch file hands it (the
    # URDF that xacro rendered, the namespace) is what the test checks.
    root = tmp_path / 'fake_rsp'
    (root / 'share/ament_index/resource_index/packages').mkdir(parents=True)
    (root / 'share/ament_index/resource_index/packages/robot_state_publisher').touch()
    exe = root / 'lib/robot_state_publisher/robot_state_publisher'
    exe.parent.mkdir(parents=True)
    exe.write_text(FAKE_RSP.format(python=sys.executable))
    exe.chmod(0o755)
    return root


def test_robot_state_publisher_gets_the_urdf_of_the_preset(launch, probe, prefix,
                                                           fake_rsp_prefix, tmp_path):
    params_file = tmp_path / 'short_stroke.yaml'
    params_file.write_text(textwrap.dedent('''\
        /**:
          ros__parameters:
            stroke_min: -0.05
            stroke_max: 0.12
        '''))
    out = tmp_path / 'rsp.json'
    env = launch_env(prefix, fake_rsp_prefix)
    env['FAKE_RSP_OUT'] = str(out)
    proc = launch(['leadscrew_sim.launch.py', 'namespace:=ax2', 'joint_prefix:=z_',
                   'preset:=tr8x8', f'params_file:={params_file}',
                   f'record_dir:={tmp_path / "runs"}', 'robot_state_publisher:=true'], env)
    got = first_messages(probe, ['/ax2/axis/joint_states'], proc)
    assert '/ax2/axis/joint_states' in got, proc.output()
    assert list(got['/ax2/axis/joint_states'].name) == ['z_screw_joint', 'z_nut_joint'], \
        proc.output()
    # The stand-in is ready for SIGINT once its output exists.
    assert probe.spin_until(out.is_file, 30.0), proc.output()
    rsp = json.loads(out.read_text())
    assert '__ns:=/ax2' in rsp['argv']
    # It listens to the node's states (its own joint_states remapped to axis/joint_states).
    assert 'joint_states:=axis/joint_states' in rsp['argv'], rsp['argv']
    robot = yourdfpy.URDF.load(io.StringIO(rsp['parameters']['robot_description']),
                               build_collision_scene_graph=False, load_meshes=False,
                               load_collision_meshes=False)
    preset = ros_parameters(prefix / 'share/leadscrew_sim/config/tr8x8.yaml')
    lead = preset['pitch'] * preset['starts']
    nut, screw = robot.joint_map['z_nut_joint'], robot.joint_map['z_screw_joint']
    assert (nut.limit.lower, nut.limit.upper) == pytest.approx((-0.05, 0.12))
    assert nut.limit.velocity / screw.limit.velocity * 2 * math.pi == pytest.approx(lead)
    assert screw.limit.effort == pytest.approx(preset['max_torque'])
    rc = proc.ctrl_c()
    assert_clean_exit(proc, rc, processes=2)


@pytest.mark.slow
def test_ctrl_c_ends_every_node_cleanly_ten_times_in_ten(launch, probe, prefix, tmp_path):
    # Ctrl-C reaches each node twice (from the terminal's process group, then relayed by
    # launch); a second SIGINT during teardown must not end a node with -2. Half of the
    # tries record (a file to close), half do not (a quick exit, the racier case).
    topics = ['/x_axis/axis/joint_states', '/y_axis/axis/joint_states']
    for attempt in range(10):
        record = 'true' if attempt % 2 else 'false'
        proc = launch(['gantry.launch.py', f'record:={record}',
                       f'record_dir:={tmp_path / f"runs{attempt}"}'], launch_env(prefix))
        got = first_messages(probe, topics, proc)
        assert sorted(got) == topics, (attempt, proc.output())
        rc = proc.ctrl_c()
        assert_clean_exit(proc, rc, processes=2)


# -- the real ros2 command line against one running node ----------------------------------

def ros2_cli(ros2, env, *args, timeout=40):
    """Run `ros2 <args>` as a shell that sourced the prefix does; return the CompletedProcess."""
    return subprocess.run([sys.executable, str(ros2), *args], env=env, capture_output=True,
                          text=True, timeout=timeout)


def param_cli(ros2, env, verb, *args):
    # --no-daemon: no ros2 daemon left behind; --timeout: time to discover the node.
    return ros2_cli(ros2, env, 'param', verb, '--no-daemon', '--timeout', '15', *args)


@pytest.fixture(scope='module')
def ax5(ros2, prefix, tmp_path_factory):
    """Run `ros2 launch leadscrew_sim leadscrew_sim.launch.py namespace:=ax5` for the module."""
    tmp = tmp_path_factory.mktemp('ax5')
    env = launch_env(prefix)
    proc = Launch(ros2, ['leadscrew_sim.launch.py', 'namespace:=ax5',
                         f'record_dir:={tmp / "runs"}'], env, tmp / 'launch.log')
    proc.record_dir, proc.env, proc.tmp = tmp / 'runs', env, tmp
    yield proc
    try:
        assert proc.ctrl_c() == 0, proc.output()
    finally:
        proc.kill()


NODE = '/ax5/leadscrew_sim_node'


def test_cli_param_set_get_and_refusal(ros2, ax5):
    env = ax5.env
    res = param_cli(ros2, env, 'set', NODE, 'backlash', '0')   # an integer for a double
    assert res.returncode == 0 and 'Set parameter successful' in res.stdout, \
        res.stdout + res.stderr + ax5.output()
    res = param_cli(ros2, env, 'get', NODE, 'backlash')
    assert res.returncode == 0 and res.stdout.strip() == 'Double value is: 0.0', \
        res.stdout + res.stderr
    before = param_cli(ros2, env, 'get', NODE, 'mu_k').stdout
    res = param_cli(ros2, env, 'set', NODE, 'mu_k', '-1')
    assert 'Set parameter successful' not in res.stdout, res.stdout
    assert 'Setting parameter failed' in res.stderr and 'mu_k' in res.stderr.split(
        'Setting parameter failed', 1)[1], res.stdout + res.stderr
    assert param_cli(ros2, env, 'get', NODE, 'mu_k').stdout == before


def test_cli_param_dump_load_round_trip(ros2, ax5):
    env = ax5.env
    # Jazzy's `ros2 param dump <node>` prints the YAML (no --output-dir any more).
    res = param_cli(ros2, env, 'dump', NODE)
    assert res.returncode == 0, res.stdout + res.stderr + ax5.output()
    dumped = yaml.safe_load(res.stdout)
    params = dumped[NODE]['ros__parameters']
    assert {'backlash', 'mu_k', 'record_dir'} <= set(params), sorted(params)
    path = ax5.tmp / 'dump.yaml'
    path.write_text(res.stdout)
    res = param_cli(ros2, env, 'load', NODE, str(path))
    assert res.returncode == 0, res.stdout + res.stderr
    # Every parameter is set, or refused for being read-only, or (an rclpy limitation:
    # load re-parses str(value), and YAML 1.1 reads '1e-05' as a string) a double
    # printed without a dot is refused as a string; none for another reason.
    for name, reason in re.findall(r'^Set parameter (\S+) failed: (.*)$', res.stderr, re.M):
        if 'read-only' in reason:
            continue
        text = str(params[name])
        assert isinstance(params[name], float) and 'e' in text and '.' not in text and \
            "got 'Type.STRING'" in reason, (name, reason)
    loaded = set(re.findall(r'^Set parameter (\S+) successful', res.stdout, re.M))
    assert {'backlash', 'mu_k'} <= loaded, res.stdout
    after = yaml.safe_load(param_cli(ros2, env, 'dump', NODE).stdout)
    assert after == dumped


def test_cli_service_call_record(ros2, ax5):
    res = ros2_cli(ros2, ax5.env, 'service', 'call', f'{NODE}/record', 'std_srvs/srv/SetBool',
                   '{data: true}')
    assert res.returncode == 0 and 'success=True' in res.stdout, \
        res.stdout + res.stderr + ax5.output()
    match = re.search(r"message='[^']*?(/\S+?\.mcap)", res.stdout)
    assert match, res.stdout
    file = Path(match.group(1))
    assert file.parent == ax5.record_dir and file.is_file(), (file, sorted(
        ax5.record_dir.iterdir()))


# -- colcon build, source install/setup.bash, ros2 run ---------------------------------------

COLCON = 'colcon-common-extensions==0.3.0'


@pytest.fixture(scope='session')
def colcon(ros2):
    """Path of `colcon`, installed into the tools venv when absent."""
    # Not into the test venv: it brings pytest plugins (pytest-cov, -repeat, -rerunfailures).
    exe = TOOLS_VENV / 'bin' / 'colcon'
    with open(Path(sys.prefix) / '.ros2-tools-venv.lock', 'w') as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        if not exe.is_file():
            res = subprocess.run([str(TOOLS_VENV / 'bin' / 'python'), '-m', 'pip',
                                  '--disable-pip-version-check', '-q', 'install', COLCON],
                                 capture_output=True, text=True)
            if res.returncode != 0:
                pytest.skip(f'cannot install {COLCON}: {res.stderr[-500:]}')
    return exe


def test_colcon_build_source_and_ros2_run(ros2, colcon, probe, tmp_path):
    ws = tmp_path / 'ws'
    shutil.copytree(REPO, ws / 'src' / 'leadscrew_sim', ignore=shutil.ignore_patterns(
        '.venv', '.git', 'build', 'install', 'log', 'runs', '.ros_log', '*.egg-info',
        '__pycache__', '.hypothesis'))
    env = launch_env()
    # Run on the test venv's python, as `ros2` is, so setup.py and the node's shebang use it.
    res = subprocess.run([sys.executable, str(colcon), 'build', '--packages-select',
                          'leadscrew_sim'], cwd=ws, env=env, capture_output=True, text=True,
                         timeout=120)
    assert res.returncode == 0, res.stdout + res.stderr
    assert (ws / 'install/leadscrew_sim/lib/leadscrew_sim/leadscrew_sim_node').is_file()
    script = (f'ros2() {{ {sys.executable} {ros2} "$@"; }}\n'
              'source install/setup.bash && '
              'ros2 run leadscrew_sim leadscrew_sim_node --ros-args -p record:=false '
              f'-p record_dir:={tmp_path / "runs"}\n')
    log = open(tmp_path / 'run.log', 'wb')
    proc = subprocess.Popen(['bash', '-c', script], cwd=ws, env=env, stdout=log,
                            stderr=subprocess.STDOUT, start_new_session=True)
    run = type('Run', (), {'proc': proc})
    try:
        got = first_messages(probe, ['/axis/joint_states'], run, timeout=60.0)
        output = (tmp_path / 'run.log').read_text(errors='replace')
        assert '/axis/joint_states' in got, output
        assert list(got['/axis/joint_states'].name) == ['screw_joint', 'nut_joint']
        os.killpg(proc.pid, signal.SIGINT)       # ros2 run does not forward SIGINT
        rc = proc.wait(timeout=30)
        assert rc == 0, (tmp_path / 'run.log').read_text(errors='replace')
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait(timeout=10)
        log.close()
