"""
Test harness: isolates ROS traffic and provides the process and rclpy fixtures.

Shared helper functions and constants live in helpers.py; test modules in
every subdirectory import them with ``import helpers`` (this directory is on
sys.path, see below).
"""
import os
from pathlib import Path
import sys

import pytest

HERE = Path(__file__).resolve().parent
# pytest's prepend import mode already puts this directory (a conftest.py
# without __init__.py) on sys.path; made explicit so that ``import helpers``
# works in every subdirectory under any import mode.
if str(HERE) not in sys.path:
    sys.path.insert(0, str(HERE))

# Every test session gets its own DDS domain, restricted to this host, so the
# ROS 2 processes that other users run on domain 0 never reach our tests.
os.environ['ROS_DOMAIN_ID'] = os.environ.get(
    'LEADSCREW_TEST_DOMAIN_ID', str(1 + os.getpid() % 100))
os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
os.environ.pop('ROS_LOCALHOST_ONLY', None)
os.environ.setdefault('ROS_LOG_DIR', str(HERE.parent / '.ros_log'))
os.environ.setdefault('AMENT_PREFIX_PATH', sys.prefix)


def _has_avx2_fma():
    try:
        flags = Path('/proc/cpuinfo').read_text().split()
    except OSError:
        return False
    return 'avx2' in flags and 'fma' in flags


# numpy's and scipy's bundled OpenBLAS pick their kernels by the CPU when they load
# (SkylakeX on AVX-512 hosts, Haswell on AVX2 and AMD Zen hosts), and the kernels differ
# in the last bits of a product or an SVD. identify's fits take none of their sums from
# OpenBLAS (test/cli/test_identify_kernels.py runs one under two kernels); the suite
# still pins the Haswell kernels (any AVX2 + FMA host runs them), before numpy loads, so
# that every other computation (eigenvalues, spectra) rounds alike on any host. CLI
# subprocesses inherit the setting.
if _has_avx2_fma():
    os.environ.setdefault('OPENBLAS_CORETYPE', 'Haswell')

from helpers import NodeProcess, Ros  # noqa: E402  (after the environment is set)


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


@pytest.fixture
def ros():
    """Yield a test-side rclpy helper (helpers.Ros), closed after the test."""
    r = Ros()
    yield r
    r.close()


# `make test` runs the suite in two parts: the tests marked `alone` by themselves, after the
# others have run in two worker processes (pytest-xdist). Alone are the tests that start ROS
# nodes, a ros2_control stack, a live server or a browser, or bound a wall time: a second
# worker on the same two cores would stretch their timing, not their results.
ALONE_DIRS = ('ros', 'ros2_control')
ALONE_FILES = {'package/test_readme.py', 'package/test_numba_cache.py',
               'analysis/test_stability_grid.py', 'cli/test_play_foxglove.py'}
ALONE_FIXTURES = {'run_exe', 'ros'}        # test/ros2_control's own fixtures: ALONE_DIRS


def pytest_collection_modifyitems(config, items):
    """Mark the tests that run by themselves (`alone`; see ALONE_DIRS)."""
    for item in items:
        try:
            rel = Path(str(item.path)).resolve().relative_to(HERE).as_posix()
        except ValueError:
            continue
        if (rel.split('/')[0] in ALONE_DIRS or rel in ALONE_FILES
                or ALONE_FIXTURES & set(item.fixturenames)):
            item.add_marker(pytest.mark.alone)
