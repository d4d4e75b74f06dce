"""
Every command of the README's plain-venv block and of doc/guide.md's offline-tools block works.

The block after the ``venv-commands`` marker is run line by line with bash,
in a scratch directory whose ``.venv`` is this repository's virtual
environment, as a user would run it from the repository root. A command
that runs until Ctrl-C (the node) must bring up ``/axis/joint_states`` and exit
0 on SIGINT; the others must exit 0. The block must not be empty.

The block after the ``offline-commands`` marker is run line by line, in
order, in another scratch directory with the venv's ``bin/`` first on the
PATH (and ``AMENT_PREFIX_PATH`` set, as the venv block does); every line
must exit 0, except lines marked ``# needs a running node``, which are
skipped.
"""
import os
import re
import signal
import subprocess
import sys

import pytest

from helpers import REPO, wait_for

MARKER = '<!-- venv-commands'
OFFLINE_MARKER = '<!-- offline-commands'
#: The page holding the offline-tools block (the README is the front door).
GUIDE = 'doc/guide.md'
#: The comment that marks a line of the offline block the test skips.
NEEDS_NODE = '# needs a running node'


def venv_commands(marker=MARKER, page='README.md'):
    """Return the lines of the bash block after ``marker`` of ``page`` (README, doc/guide)."""
    text = (REPO / page).read_text()
    start = text.index(marker)
    block = re.search(r'```bash\n(.*?)```', text[start:], re.S)
    return [line for line in block.group(1).splitlines() if line.strip()]


def test_the_block_exists_and_names_the_venv_executables():
    lines = venv_commands()
    assert 'source .venv/bin/activate' in lines
    assert any(line.startswith('leadscrew_sim_node ') for line in lines)
    assert any(line.startswith('leadscrew_sim ') for line in lines)


def test_the_offline_block_exists_and_uses_the_command():
    lines = venv_commands(OFFLINE_MARKER, GUIDE)
    assert lines and all(line.startswith(('leadscrew_sim ', 'printf ')) for line in lines)


@pytest.fixture(scope='module')
def scratch(tmp_path_factory):
    """Return a directory holding a link to the repository's .venv, as the root does."""
    venv = REPO / '.venv'
    if not (venv / 'lib' / 'leadscrew_sim' / 'leadscrew_sim_node').exists():
        pytest.skip('the venv executables exist after make setup')
    d = tmp_path_factory.mktemp('readme')
    (d / '.venv').symlink_to(venv)
    return d


def joint_states_seen(env, timeout):
    """Return True if /axis/joint_states is published within ``timeout`` s (another process)."""
    code = ('import rclpy, sys, time\n'
            'from sensor_msgs.msg import JointState\n'
            'rclpy.init(); n = rclpy.create_node("readme_probe"); got = []\n'
            'n.create_subscription(JointState, "/axis/joint_states", got.append, 10)\n'
            f'end = time.monotonic() + {timeout}\n'
            'while not got and time.monotonic() < end:\n'
            '    rclpy.spin_once(n, timeout_sec=0.1)\n'
            'sys.exit(0 if got else 1)\n')
    return subprocess.run([sys.executable, '-c', code], env=env,
                          timeout=timeout + 30).returncode == 0


@pytest.mark.slow
@pytest.mark.timeout(600)
def test_every_venv_command_runs(scratch):
    env = dict(os.environ)
    env.pop('AMENT_PREFIX_PATH', None)          # the block sets it
    prelude = []
    for line in venv_commands():
        if line.startswith(('export ', 'source ')):
            prelude.append(line)
            continue
        script = '\n'.join(prelude + [line])
        if '_node' in line or 'leadscrew_sim.node' in line:
            script = '\n'.join(prelude + ['exec ' + line])      # Ctrl-C reaches the node
            proc = subprocess.Popen(['bash', '-c', script], cwd=scratch, env=env,
                                    stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                                    start_new_session=True)
            try:
                probe_env = dict(env, AMENT_PREFIX_PATH=str(REPO / '.venv'))
                assert joint_states_seen(probe_env, 60.0), line
            finally:
                os.killpg(proc.pid, signal.SIGINT)
                out = proc.communicate(timeout=60)[0].decode(errors='replace')
            assert proc.returncode == 0, f'{line}\n{out[-3000:]}'
        else:
            res = subprocess.run(['bash', '-c', script], cwd=scratch, env=env,
                                 capture_output=True, text=True, timeout=300)
            assert res.returncode == 0, f'{line}\n{res.stdout[-2000:]}\n{res.stderr[-2000:]}'
    assert wait_for(lambda: (scratch / 'runs' / 'ss.png').is_file(), 1.0)


@pytest.mark.slow
@pytest.mark.timeout(600)
def test_every_offline_command_runs(tmp_path):
    bin_dir = REPO / '.venv' / 'bin'
    if not (bin_dir / 'leadscrew_sim').exists():
        pytest.skip('.venv/bin/leadscrew_sim exists after make setup')
    env = dict(os.environ, PATH=f'{bin_dir}{os.pathsep}{os.environ.get("PATH", "")}',
               AMENT_PREFIX_PATH=str(REPO / '.venv'))
    ran = 0
    for line in venv_commands(OFFLINE_MARKER, GUIDE):
        if NEEDS_NODE in line:
            continue
        res = subprocess.run(['bash', '-c', line], cwd=tmp_path, env=env, capture_output=True,
                             text=True, timeout=300)
        assert res.returncode == 0, f'{line}\n{res.stdout[-2000:]}\n{res.stderr[-2000:]}'
        ran += 1
    assert ran >= 5
    assert (tmp_path / 'ss.png').is_file() and (tmp_path / 'runs' / 'ss.resim.mcap').is_file()
