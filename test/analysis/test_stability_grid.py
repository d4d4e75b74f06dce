"""
Grids of the stability analysis: the same rows however distributed, and bad input refused.

Local worker processes and a real Dask cluster (a scheduler and two workers
started from the venv's ``dask`` command on localhost) give rows
bit-identical to a run in this process.
"""
import os
from pathlib import Path
import socket
import subprocess
import sys
import time

import pytest

from leadscrew_sim.analysis.stability.executors import identical
from leadscrew_sim.analysis.stability.grid import expand, parse_axis
from leadscrew_sim.analysis.stability.table import stability_table
from leadscrew_sim.core.params import ParameterError
from leadscrew_sim.core.presets import load_preset

GRID = ['speed=3e-4:4e-3:3:log', 'coupling_damping=0:2e-4:2']
DASK = Path(sys.executable).with_name('dask')


def table(**kw):
    """Run the small test grid of the stick_slip preset under the ideal drive."""
    return stability_table(load_preset('stick_slip'), GRID, drive='ideal', duration=0.3, **kw)


@pytest.fixture(scope='module')
def serial():
    """Return the rows of the grid run in this process."""
    res = table(workers=1)
    assert res['complete'] and len(res['rows']) == 6
    assert not any(r['error'] for r in res['rows'])
    return res['rows']


def test_two_workers_bit_identical(serial):
    """Two local worker processes give the rows of one process, bit for bit."""
    res = table(workers=2)
    assert res['complete']
    assert identical(res['rows'], serial)


def free_port():
    """Return a TCP port nobody listens on (just released)."""
    with socket.socket() as s:
        s.bind(('127.0.0.1', 0))
        return s.getsockname()[1]


@pytest.fixture
def cluster(tmp_path):
    """Start a Dask scheduler and two single-threaded workers on localhost; yield its address."""
    if not DASK.exists():
        pytest.skip('the dask command is not installed in this environment')
    port = free_port()
    addr = f'tcp://127.0.0.1:{port}'
    env = dict(os.environ)
    procs = [subprocess.Popen([str(DASK), 'scheduler', '--host', '127.0.0.1', '--port',
                               str(port), '--no-dashboard'], env=env,
                              stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)]
    try:
        for _ in range(2):
            procs.append(subprocess.Popen(
                [str(DASK), 'worker', addr, '--nworkers', '1', '--nthreads', '1',
                 '--no-dashboard', '--local-directory', str(tmp_path)], env=env,
                stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL))
        from distributed import Client
        with Client(addr, timeout=30) as client:
            client.wait_for_workers(2, timeout=60)
        yield addr
    finally:
        for p in reversed(procs):
            p.terminate()
        for p in procs:
            try:
                p.wait(timeout=10)
            except subprocess.TimeoutExpired:
                p.kill()


def test_dask_cluster_bit_identical(serial, cluster):
    """A scheduler with two workers gives the rows of the local run, bit for bit."""
    res = table(scheduler=cluster)
    assert res['complete']
    assert identical(res['rows'], serial)


def test_unreachable_scheduler_fails_fast():
    """No scheduler at the address: one ParameterError naming it, within 10 s."""
    t0 = time.monotonic()
    with pytest.raises(ParameterError, match='scheduler') as info:
        table(scheduler=f'tcp://127.0.0.1:{free_port()}')
    assert time.monotonic() - t0 < 10.0
    assert '\n' not in str(info.value)


@pytest.mark.parametrize('grid, speed, word', [
    (['nonsense=0:1:3'], 1e-3, 'nonsense'),
    (['mu_k=0:3:3'], 1e-3, 'mu_k'),
    (['mu_k=0.1:0.2:1'], 1e-3, 'minimum 2'),
    (['mu_k=0.1:0.2:2', 'mu_s=0.2:0.3:2', 'coupling_damping=0:1:2',
      'guide_viscous=0:1:2'], 1e-3, 'at most 3'),
    ([], 0.0, 'speed'),
    (['speed=-1e-3:1e-3:3'], None, 'speed'),
])
def test_bad_input_one_line(grid, speed, word):
    """Bad axes and speeds: one ParameterError line naming the parameter."""
    with pytest.raises(ParameterError, match=word) as info:
        stability_table(load_preset('stick_slip'), grid, speed=speed, workers=1)
    assert '\n' not in str(info.value)


def test_axes_values_and_order():
    """A log axis is geometric, a linear one even; the first axis varies slowest."""
    p = load_preset('stick_slip')
    name, vals = parse_axis('speed=1e-4:1e-2:3:log', p)
    assert name == 'speed' and vals == pytest.approx([1e-4, 1e-3, 1e-2], rel=1e-12)
    cases = expand([('a', [1, 2]), ('b', [3, 4, 5])])
    assert [c['b'] for c in cases] == [3, 4, 5, 3, 4, 5] and cases[3]['a'] == 2


def test_reused_models_give_the_rows_of_new_ones(serial):
    """A batch reuses one reset model per parameter set: the rows of a new model per case."""
    from leadscrew_sim.analysis.stability.grid import run_case
    base = load_preset('stick_slip')
    cases = expand([parse_axis(g, base) for g in GRID])
    fresh = [run_case(base, c, None, 'ideal', 'both', 0.3) for c in cases]   # no cache
    assert identical(fresh, serial)


def test_cases_grouped_by_parameter_set():
    """The batches' order puts the cases of one parameter set together, keeping their order."""
    from leadscrew_sim.analysis.stability.executors import grouped_order
    cases = expand([('speed', [1.0, 2.0, 3.0]), ('mu_k', [0.1, 0.2])])
    order = grouped_order(cases)
    assert [cases[i]['mu_k'] for i in order] == [0.1] * 3 + [0.2] * 3
    assert [cases[i]['speed'] for i in order] == [1.0, 2.0, 3.0] * 2
