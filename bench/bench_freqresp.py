"""
Benchmark the sine dwell: 50 frequencies over two decades, the tr12x3 velocity loop.

Run: .venv/bin/python bench/bench_freqresp.py [--points 50] [--fmin 1] [--fmax 100]
[--speed 0.01] [--workers 1 2] [--repeat 3]

The velocity loop's L of tr12x3, measured by injection at the drive period
(sine dwell, 3 periods settled, 5 kept, one amplitude), from steady sliding
at ``--speed`` [m/s] (0: at rest, the thread stuck at small amplitudes). It
reports the wall time of the whole library call (kernel warm, so a first
compile is not counted) per worker count, the best of ``--repeat``, the
simulated time and steps it ran, and checks the tables are bit-identical
across worker counts. The target of issue 25: under 10 s.
"""
import argparse
import time

import numpy as np

from leadscrew_sim.analysis.freqresp.measure import measurement_step, simulated_response
from leadscrew_sim.analysis.freqresp.sine import grid_frequency
from leadscrew_sim.analysis.stability.executors import warm
from leadscrew_sim.core.presets import load_preset


def simulated_steps(p, fmin, fmax, points, settle, periods, settle_time, dt):
    """Return (simulated seconds, steps) of the dwell's runs."""
    f = np.unique([grid_frequency(x, dt)[0] for x in np.geomspace(fmin, fmax, points)])
    total = 0.0
    for fi in f:
        total += (max(settle, int(np.ceil(settle_time * fi))) + periods) / fi
    return total, int(round(total / dt)), len(f)


def main():
    """Run the benchmark and print one line per worker count."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[1])
    ap.add_argument('--points', type=int, default=50)
    ap.add_argument('--fmin', type=float, default=1.0)
    ap.add_argument('--fmax', type=float, default=100.0)
    ap.add_argument('--speed', type=float, default=0.01, help='nut speed [m/s] (0: at rest)')
    ap.add_argument('--workers', type=int, nargs='+', default=[1, 2])
    ap.add_argument('--repeat', type=int, default=3)
    a = ap.parse_args()
    p = load_preset('tr12x3')
    warm()
    kw = dict(loop='velocity', quantity='L', fmin=a.fmin, fmax=a.fmax, points=a.points,
              amplitudes=[0.005], speed=a.speed)
    from leadscrew_sim.analysis.freqresp.measure import _settle_time
    dt = measurement_step(p, 1e-3, 'velocity')
    sim_s, steps, nf = simulated_steps(p, a.fmin, a.fmax, a.points, 3, 5,
                                       _settle_time(p, None, 'velocity', a.speed, None), dt)
    print(f'tr12x3 velocity loop L, {nf} frequencies {a.fmin:g}..{a.fmax:g} Hz, speed '
          f'{a.speed:g} m/s: {sim_s:.1f} s simulated in {steps} steps of {dt * 1e6:.1f} us')
    ref = None
    for w in a.workers:
        best = float('inf')
        for _ in range(a.repeat):
            t0 = time.perf_counter()
            r = simulated_response(p, workers=w, **kw)[0]
            best = min(best, time.perf_counter() - t0)
        same = '' if ref is None else (
            ', bit-identical to 1 worker' if r.response.tobytes() == ref.response.tobytes()
            else ', DIFFERS from 1 worker')
        ref = r if ref is None else ref
        print(f'workers {w}: {best:.2f} s (best of {a.repeat}){same}')


if __name__ == '__main__':
    main()
