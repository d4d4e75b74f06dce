"""
Time the kernel of this tree against another commit's, interleaved in one run.

Run: .venv/bin/python bench/bench_ab.py --ref COMMIT [--rounds 3]

The other commit is checked out into a temporary git worktree with its own
numba cache (compiled once, about 30 s). Each round times, in a fresh
process per tree, the servo drive in position mode tracking x = 20 mm
sin(2 pi 0.5 Hz t) for 20 s simulated at dt = 1 ms on three presets (best
of 3 runs each); the rounds alternate the trees, so load on a shared host
hits both alike. Prints ns per substep per tree and their ratio (this tree
over the other), the median over the rounds.
"""
import argparse
import json
import os
from pathlib import Path
import statistics
import subprocess
import sys
import tempfile

REPO = Path(__file__).resolve().parents[1]

#: The timed run, executed in the tree on sys.path[0]; prints {preset: ns per substep}.
TIMED = r'''
import json, math, time
import numpy as np
from leadscrew_sim import LeadScrewModel, load_preset
from leadscrew_sim.core.engine import drive as D
out = {}
for name in ('tr12x3', 'anti_backlash', 'tr8x8'):
    p = load_preset(name)
    m = LeadScrewModel(p, dt=1e-3)
    n = 20000
    x = 0.02 * np.sin(2 * math.pi * 0.5 * np.arange(n) * 1e-3)
    rows = np.full((n, 4), math.nan)
    rows[:, 0] = D.MODE_POSITION
    rows[:, 1] = [m.nut_to_motor(v) for v in x]
    best = math.inf
    for _ in range(3):
        mm = LeadScrewModel(p, dt=1e-3)
        t0 = time.perf_counter()
        mm.run(None, commands=rows)
        best = min(best, time.perf_counter() - t0)
    out[name] = best / (n * m.nsub) * 1e9
print(json.dumps(out))
'''


def run(tree, cache):
    """Return {preset: ns per substep} of the kernel in ``tree`` (its numba cache ``cache``)."""
    env = dict(os.environ, PYTHONPATH=str(tree), NUMBA_CACHE_DIR=str(cache),
               AMENT_PREFIX_PATH=os.environ.get('AMENT_PREFIX_PATH', sys.prefix))
    out = subprocess.run([sys.executable, '-c', TIMED], env=env, capture_output=True,
                         text=True, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


def main():
    """Check out the other commit, time both trees in alternating rounds, print the ratios."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[1])
    ap.add_argument('--ref', required=True, help='the commit to compare with')
    ap.add_argument('--rounds', type=int, default=3, help='alternating rounds (default 3)')
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        other = Path(tmp) / 'other'
        subprocess.run(['git', '-C', str(REPO), 'worktree', 'add', '--detach', str(other),
                        args.ref], check=True, capture_output=True)
        try:
            caches = {'this': Path(tmp) / 'cache_this', 'other': Path(tmp) / 'cache_other'}
            trees = {'this': REPO, 'other': other}
            print('compiling both kernels (about 30 s each) ...', flush=True)
            results = {k: [] for k in trees}
            for r in range(args.rounds + 1):             # round 0 compiles, not counted
                for k in (('this', 'other') if r % 2 else ('other', 'this')):
                    ns = run(trees[k], caches[k])
                    if r:
                        results[k].append(ns)
                if r:
                    print(f'round {r}/{args.rounds} done', flush=True)
        finally:
            subprocess.run(['git', '-C', str(REPO), 'worktree', 'remove', '--force',
                            str(other)], capture_output=True)
    print(f'ns per substep, servo position mode, best of 3 per round, median of '
          f'{args.rounds} rounds; this tree against {args.ref}')
    print(f'{"preset":<15}{"this":>10}{"other":>10}{"this/other":>12}')
    for name in results['this'][0]:
        a = statistics.median(r[name] for r in results['this'])
        b = statistics.median(r[name] for r in results['other'])
        print(f'{name:<15}{a:>10.1f}{b:>10.1f}{a / b:>12.3f}')


if __name__ == '__main__':
    main()
