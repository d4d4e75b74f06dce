"""
Time the kernel with the ageing on against the same kernel with it off, side by side.

Run: .venv/bin/python bench/bench_ageing.py [--rounds 5]

The servo drive tracks x = 20 mm sin(2 pi 0.5 Hz t) in position mode for
20 s simulated at dt = 1 ms on three presets; "on" sets flank wear, a
lubricant and a heated, growing screw (every ageing process at once), "off"
leaves them at their defaults (all off). The rounds alternate on and off in
one process, best of 3 runs each, so load on a shared host hits both alike.
The dry thread's friction is set to the wet one's, so both runs take the same
path through the friction solver and the ratio is the ageing's bookkeeping.
Prints ns per substep of each and their ratio (on / off), the median over
the rounds. The ageing is integrated once per step, so its cost per substep
is its per-step work spread over the substeps.
"""
import argparse
import math
import statistics
import time

import numpy as np

from leadscrew_sim import LeadScrewModel, load_preset
from leadscrew_sim.core.engine import drive as D

PRESETS = ('tr12x3', 'anti_backlash', 'tr8x8')
#: Every ageing process on (rates chosen so the run wears visibly, nothing jams).
AGEING = dict(wear_rate=1e-12, ageing_speedup=1e3, lubricant_life=100.0,
              screw_heat_capacity=50.0, screw_heat_loss=0.5)


def rows_for(p, n):
    """Return the position-mode command rows of the tracked sine, and the model's substeps."""
    m = LeadScrewModel(p, dt=1e-3)
    x = 0.02 * np.sin(2 * math.pi * 0.5 * np.arange(n) * 1e-3)
    rows = np.full((n, 4), math.nan)
    rows[:, 0] = D.MODE_POSITION
    rows[:, 1] = [m.nut_to_motor(v) for v in x]
    return rows, m.nsub


def best_time(p, rows, repeats=3):
    """Return the best wall time [s] of ``repeats`` runs of ``rows`` on a new model of ``p``."""
    best = math.inf
    for _ in range(repeats):
        m = LeadScrewModel(p, dt=1e-3)
        t0 = time.perf_counter()
        m.run(None, commands=rows)
        best = min(best, time.perf_counter() - t0)
    return best


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[1])
    ap.add_argument('--rounds', type=int, default=5)
    ap.add_argument('--seconds', type=float, default=20.0, help='simulated s per run')
    args = ap.parse_args()
    n = int(args.seconds * 1000)
    print(f'{"preset":14s} {"off ns/sub":>11s} {"on ns/sub":>10s} {"on/off":>7s}')
    for name in PRESETS:
        off = load_preset(name)
        # the dry thread as the wet one: the same motion, so the ratio is the ageing's own cost
        on = load_preset(name, mu_s_dry=off.mu_s, mu_k_dry=off.mu_k, **AGEING)
        rows, nsub = rows_for(off, n)
        best_time(off, rows[:100], 1)          # compile and warm both paths
        best_time(on, rows[:100], 1)
        t_off, t_on = [], []
        for k in range(args.rounds):
            pair = [(off, t_off), (on, t_on)]
            for p, out in (pair if k % 2 == 0 else pair[::-1]):
                out.append(best_time(p, rows) / (n * nsub) * 1e9)
        a, b = statistics.median(t_off), statistics.median(t_on)
        print(f'{name:14s} {a:11.1f} {b:10.1f} {b / a:7.3f}   '
              f'(ratios per round: {", ".join(f"{y / x:.3f}" for x, y in zip(t_off, t_on))})')


if __name__ == '__main__':
    main()
