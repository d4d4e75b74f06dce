"""
Benchmark the stability map: the nonlinear runs against the bare kernel, workers, Dask.

Run: .venv/bin/python bench/bench_stability.py [--speeds 8] [--dampings 4] [--duration 2]
[--drive velocity] [--no-dask]
or, the 10,000-case map of tr12x3:
.venv/bin/python bench/bench_stability.py --preset tr12x3 --speeds 100 --dampings 100

The map is the preset (default stick_slip) over speed (0.3 .. 4 mm/s, log) x
its second axis, ``--method nonlinear`` (two runs of ``--duration`` per
case): coupling_damping (0 .. 1e-3 N m s/rad) for a compliant coupling,
else payload_mass (its value .. 3 times it). It reports: the wall time of the map in this
process (1 worker); the bare kernel time of the same runs (LeadScrewModel.run
with the same command rows and steps, nothing else; velocity drive only);
the map on 2 local worker processes; and on a Dask LocalCluster of 2
single-threaded worker processes (the cluster's start-up not counted). Each
distributed table is checked bit-identical to the serial one.
"""
import argparse
import math
import time

import numpy as np

from leadscrew_sim.analysis.stability import operating_point
from leadscrew_sim.analysis.stability.executors import identical, warm
from leadscrew_sim.analysis.stability.grid import case_params, expand, parse_axis
from leadscrew_sim.analysis.stability.nonlinear import SMALL_PERTURBATION
from leadscrew_sim.analysis.stability.table import stability_table
from leadscrew_sim.core.drive_modes import MODE_VELOCITY
from leadscrew_sim.core.model import LeadScrewModel
from leadscrew_sim.core.presets import load_preset
from leadscrew_sim.core.steady import place_sliding


def bare_kernel(base, grid, duration, dt=1e-3):
    """Return the wall time of the model runs alone (2 per case), velocity drive."""
    cases = expand([parse_axis(g, base) for g in grid])
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
            model.run(None, commands=rows)
            total += time.perf_counter() - t0
    return total


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
    ap.add_argument('--no-dask', action='store_true')
    ap.add_argument('--preset', default='stick_slip')
    a = ap.parse_args()
    base = load_preset(a.preset)
    second = (f'coupling_damping=0:1e-3:{a.dampings}' if base.coupling_stiffness > 0.0 else
              f'payload_mass={base.payload_mass:g}:{3 * base.payload_mass:g}:{a.dampings}')
    grid = [f'speed=3e-4:4e-3:{a.speeds}:log', second]
    n = a.speeds * a.dampings
    warm()

    def table(**kw):
        return stability_table(base, grid, drive=a.drive, method='nonlinear',
                               duration=a.duration, **kw)

    serial, t1 = timed(lambda: table(workers=1))
    print(f'{a.preset}: {n} cases ({", ".join(grid)}), 2 runs of {a.duration:g} s each, '
          f'drive {a.drive}')
    print(f'map, 1 worker (this process)   {t1:8.2f} s')
    if a.drive == 'velocity':
        tk = bare_kernel(base, grid, a.duration)
        print(f'bare kernel, same runs         {tk:8.2f} s   (map / kernel {t1 / tk:.2f})')
    two, t2 = timed(lambda: table(workers=2))
    print(f'map, 2 local workers           {t2:8.2f} s   (speed-up {t1 / t2:.2f}, '
          f'identical {identical(two["rows"], serial["rows"])})')
    if not a.no_dask:
        from distributed import LocalCluster
        with LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                          dashboard_address=None) as cluster:
            dk, td = timed(lambda: table(scheduler=cluster.scheduler_address))
        print(f'map, Dask (2 worker processes) {td:8.2f} s   (speed-up {t1 / td:.2f}, '
              f'identical {identical(dk["rows"], serial["rows"])})')


if __name__ == '__main__':
    main()
