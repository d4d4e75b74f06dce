"""
Fixtures of the tests through the real ros2_control stack (r2c.py).

``r2c_stack`` (session): the built stack's prefix. It runs
``../shared/ros2_control/setup.sh`` once per session (an up-to-date stack
returns in 0.1 s; a first build takes about 10 minutes and prints its
progress lines to the terminal). Without ``../shared`` (a user's clone) or
without the README's prerequisites every test here is skipped with the
reason; any other build failure fails them with the build's last lines.

``axis`` (function): ``axis(**kw)`` brings up an :class:`r2c.Axis` (node,
ros2_control_node, spawned controllers) in the test's tmp_path; after the
test every process group it started is ended, and a ros2_control_node still
running with the test's parameter file fails the test's teardown.
"""
import statistics
import subprocess
import sys

import pytest
from r2c import Axis, ensure_stack, SETUP, StackBuildFailed, StackUnavailable

#: (test id, CM rate, stamp lags [ms] in a spinning window and over the test) per axis.
STAMP_LAGS = []


@pytest.fixture(scope='session')
def r2c_stack(request):
    """Return the prefix of the built ros2_control stack (skip without ../shared)."""
    if not SETUP.is_file():
        pytest.skip(f'no ros2_control stack here: {SETUP} is absent')
    capman = request.config.pluginmanager.getplugin('capturemanager')

    def say(line):
        # Shown live, past pytest's capture: a first build runs for minutes.
        if capman is None:
            sys.__stderr__.write(f'{line}\n')
            return
        with capman.global_and_fixture_disabled():
            sys.stderr.write(f'\n{line}' if line.startswith('[r2c]') else f'\n  {line}')
            sys.stderr.flush()
    try:
        return ensure_stack(say)
    except StackUnavailable as exc:
        pytest.skip(f'ros2_control stack unavailable: {exc}')
    except StackBuildFailed as exc:
        failure = str(exc)
    # Outside the except block: the report shows the build's lines, not a chained traceback.
    pytest.fail(f'building the ros2_control stack failed:\n{failure}', pytrace=False)


@pytest.fixture
def axis(r2c_stack, tmp_path, request):
    """Yield a factory of running axes (r2c.Axis); end all their processes after the test."""
    started = []

    def bring_up(**kw):
        workdir = tmp_path / f'axis{len(started)}'
        workdir.mkdir()
        a = Axis(r2c_stack, workdir, **kw)
        started.append(a)
        return a.start()

    yield bring_up
    left = []
    for a in started:
        STAMP_LAGS.append((request.node.nodeid, a.update_rate, a.lag_window, a.stamp_lags_ms()))
        left += a.stop()
    stray = subprocess.run(['pgrep', '-af', f'ros2_control_node.*{tmp_path}'],
                           capture_output=True, text=True).stdout.strip()
    assert not left and not stray, f'processes left running: {left} {stray}'


def _stats(lags):
    s = sorted(lags)
    return (f'n={len(s)} min {s[0]:.1f} median {statistics.median(s):.1f} '
            f'p99 {s[int(0.99 * (len(s) - 1))]:.1f} max {s[-1]:.1f}')


def pytest_terminal_summary(terminalreporter):
    """Print the lag of the node's joint_states stamps behind the system clock at receipt."""
    if not STAMP_LAGS:
        return
    terminalreporter.section('node joint_states: receipt (system clock) - header.stamp [ms]')
    for nodeid, rate, window, lags in STAMP_LAGS:
        if window and lags:
            terminalreporter.write_line(
                f'{nodeid.rsplit("::", 1)[-1]} (CM {rate} Hz): 0.5 s of continuous spinning: '
                f'{_stats(window)}; whole test (test-side pauses included): {_stats(lags)}')
