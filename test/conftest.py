"""Test harness: isolates ROS traffic and runs executables as real processes."""
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
SHARED = REPO.parent / 'shared'

# Every test session gets its own DDS domain, restricted to this host, so the
# ROS 2 processes that other users run on domain 0 never reach our tests.
os.environ['ROS_DOMAIN_ID'] = os.environ.get(
    'LEADSCREW_TEST_DOMAIN_ID', str(1 + os.getpid() % 100))
os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
os.environ.pop('ROS_LOCALHOST_ONLY', None)
os.environ.setdefault('ROS_LOG_DIR', str(REPO / '.ros_log'))
os.environ.setdefault('AMENT_PREFIX_PATH', sys.prefix)


class NodeProcess:
    """A leadscrew_sim executable running as a real subprocess."""

    def __init__(self, argv, log_path):
        self.log_path = log_path
        self._log = open(log_path, 'wb')
        self.proc = subprocess.Popen(
            argv, stdout=self._log, stderr=subprocess.STDOUT,
            env=dict(os.environ), start_new_session=True)

    def output(self):
        """Return everything the process printed so far."""
        self._log.flush()
        return Path(self.log_path).read_text(errors='replace')

    def send(self, sig):
        """Send a signal to the process."""
        if self.proc.poll() is None:
            self.proc.send_signal(sig)

    def wait(self, timeout):
        """Wait for exit and return the exit code."""
        return self.proc.wait(timeout=timeout)

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


@pytest.fixture
def run_exe(tmp_path):
    """Start python modules or scripts as subprocesses; stop them after."""
    procs = []

    def start(module, *args, name=None):
        argv = [sys.executable, '-m', module, *map(str, args)]
        log = tmp_path / f'{name or module.rsplit(".", 1)[-1]}-{len(procs)}.log'
        p = NodeProcess(argv, log)
        procs.append(p)
        return p

    yield start
    for p in procs:
        p.stop()


def wait_for(predicate, timeout, period=0.02):
    """Poll predicate until true or timeout; return its last value."""
    end = time.monotonic() + timeout
    while True:
        value = predicate()
        if value or time.monotonic() > end:
            return value
        time.sleep(period)
