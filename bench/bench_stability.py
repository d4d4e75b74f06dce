"""
Benchmark the stability map: the nonlinear runs against the bare kernel, workers, Dask.

Run: .venv/bin/python bench/bench_stability.py [--speeds 8] [--dampings 4] [--duration 2]
[--drive velocity] [--rounds 4] [--no-dask]
or, the 10,000-case map of tr12x3:
.venv/bin/python bench/bench_stability.py --preset tr12x3 --speeds 100 --dampings 100

The map is the preset (default stick_slip) over speed (0.3 .. 4 mm/s, log) x
its second axis, ``--method nonlinear`` (two runs of ``--duration`` per
case): coupling_damping (0 .. 1e-3 N m s/rad) for a compliant coupling,
else payload_mass (its value .. 3 times it). Four ways of running the same
cases are timed side by side: the map in this process (1 worker); the bare
kernel time of the same runs (LeadScrewModel.run with the same command rows
and steps, returning the two arrays the map reads, nothing else; velocity
drive only); the map on 2 local worker processes; and on a Dask cluster of
2 single-threaded worker processes on localhost, started with the ``dask
scheduler`` and ``dask worker`` commands (its start-up and the workers'
warm-up not counted, as the local workers are forked from a warmed parent;
no Dask client stays open between the rounds, so this process can fork). The cases
are split into ``--rounds`` blocks; each round runs one block all four ways,
in an order that rotates from round to round, so that a neighbour's load on
the shared machine falls on all four alike; the totals are printed. Each
distributed block is checked bit-identical to the serial one.
"""
import argparse
import math
import os
import socket
import subprocess
import sys
import time

import numpy as np

from leadscrew_sim.analysis.stability import operating_point
from leadscrew_sim.analysis.stability.executors import identical, run_cases, warm
from leadscrew_sim.analysis.stability.grid import case_params, expand, parse_axis
from leadscrew_sim.analysis.stability.nonlinear import SMALL_PERTURBATION
from leadscrew_sim.core.drive_modes import MODE_VELOCITY
from leadscrew_sim.core.model import LeadScrewModel
from leadscrew_sim.core.presets import load_preset
from leadscrew_sim.core.steady import place_sliding


def bare_kernel(base, cases, duration, dt=1e-3):
    """Return the wall time of the model runs alone (2 per case), velocity drive."""
    total = 0.0
    n = int(round(duration / dt))
    for case in cases:
        params, v = case_params(base, case)
        op = operating_point(params, v, 'velocity')
        for stuck in (False, True):
            model = LeadScrewModel(params, dt=dt)
            place_sliding(model, op, stuck, 1.0 if stuck else 1.0 + SMALL_PERTURBATION)
            rows = np.tile([[MODE_VELOCITY, math.nan, params.hand_sign * op['w_ref'], 0.0]],
                           (n, 1))
            t0 = time.perf_counter()
            model.run(None, commands=rows, values=('nut_velocity', 'stuck'))
            total += time.perf_counter() - t0
    return total


def start_cluster():
    """Start a Dask scheduler and 2 single-threaded workers; return (processes, address)."""
    with socket.socket() as s:
        s.bind(('127.0.0.1', 0))
        port = s.getsockname()[1]
    address = f'tcp://127.0.0.1:{port}'
    dask = os.path.join(os.path.dirname(sys.executable), 'dask')
    quiet = dict(stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    procs = [subprocess.Popen([dask, 'scheduler', '--host', '127.0.0.1', '--port', str(port),
                               '--no-dashboard'], **quiet)]
    procs += [subprocess.Popen([dask, 'worker', address, '--nthreads', '1', '--no-dashboard',
                                '--no-nanny'], **quiet) for _ in range(2)]
    from distributed import Client
    with Client(address, timeout=30) as client:
        client.wait_for_workers(2, timeout=60)
        client.run(warm)
    return procs, address


def timed(fn):
    """Return (result, wall time [s]) of fn()."""
    t0 = time.perf_counter()
    res = fn()
    return res, time.perf_counter() - t0


def main():
    """Run the benchmark and print its table."""
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[1])
    ap.add_argument('--speeds', type=int, default=8)
    ap.add_argument('--dampings', type=int, default=4)
    ap.add_argument('--duration', type=float, default=2.0)
    ap.add_argument('--drive', default='velocity', choices=('velocity', 'ideal'))
    ap.add_argument('--rounds', type=int, default=4)
    ap.add_argument('--no-dask', action='store_true')
    ap.add_argument('--preset', default='stick_slip')
    a = ap.parse_args()
    base = load_preset(a.preset)
    second = (f'coupling_damping=0:1e-3:{a.dampings}' if base.coupling_stiffness > 0.0 else
              f'payload_mass={base.payload_mass:g}:{3 * base.payload_mass:g}:{a.dampings}')
    grid = [f'speed=3e-4:4e-3:{a.speeds}:log', second]
    cases = expand([parse_axis(g, base) for g in grid])
    n = len(cases)
    warm()
    procs, address = start_cluster() if not a.no_dask else ([], None)

    def serial(block):
        return run_cases(base, block, None, a.drive, 'nonlinear', a.duration, workers=1)[0]

    def local(block):
        return run_cases(base, block, None, a.drive, 'nonlinear', a.duration, workers=2)[0]

    def dask(block):
        return run_cases(base, block, None, a.drive, 'nonlinear', a.duration,
                         scheduler=address)[0]

    ways = {'serial': serial, 'local': local}
    if a.drive == 'velocity':
        ways['bare'] = None
    if address is not None:
        ways['dask'] = dask
    total = dict.fromkeys(ways, 0.0)
    same = True
    size = math.ceil(n / max(1, a.rounds))
    blocks = [cases[i:i + size] for i in range(0, n, size)]
    for r, block in enumerate(blocks):
        order = list(ways)[r % len(ways):] + list(ways)[:r % len(ways)]
        rows = {}
        for way in order:
            if way == 'bare':
                total[way] += bare_kernel(base, block, a.duration)
            else:
                rows[way], t = timed(lambda: ways[way](block))
                total[way] += t
        same = same and all(identical(rows[w], rows['serial']) for w in rows)
    for p in procs[::-1]:
        p.terminate()
        p.wait()
    print(f'{a.preset}: {n} cases ({", ".join(grid)}), 2 runs of {a.duration:g} s each, '
          f'drive {a.drive}, {len(blocks)} rounds; rows identical: {same}')
    t1 = total['serial']
    print(f'map, 1 worker (this process)   {t1:8.2f} s')
    if 'bare' in total:
        tk = total['bare']
        print(f'bare kernel, same runs         {tk:8.2f} s   (map / kernel {t1 / tk:.2f})')
    t2 = total['local']
    extra = f', map / (kernel / 2) {t2 / (tk / 2):.2f}' if 'bare' in total else ''
    print(f'map, 2 local workers           {t2:8.2f} s   (speed-up {t1 / t2:.2f}{extra})')
    if 'dask' in total:
        td = total['dask']
        print(f'map, Dask (2 worker processes) {td:8.2f} s   (speed-up {t1 / td:.2f}, '
              f'Dask / local {td / t2:.2f})')


if __name__ == '__main__':
    main()
