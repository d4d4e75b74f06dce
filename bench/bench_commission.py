"""
Benchmark ``leadscrew_sim commission`` on the default commission recording of tr12x3.

Run: .venv/bin/python bench/bench_commission.py [--repeat 1] [--seed 11] [--bag]
[--ref COMMIT]

``simulate --excite commission`` records tr12x3 with its friction moved by the
identification tests' factors (mu_s x1.25, mu_k x0.8, Stribeck velocity
x1.3) and the axis's own sensors (a 16-bit encoder with half a count of
noise, a 1 um linear scale with 0.5 um of noise); ``commission`` then runs
as a subprocess (all stages). Printed: the wall time of the whole command,
its CPU time (one core: the bound of the wall time on an idle host) and the
load average, the stage lines on stderr, each stage's time (from
report.json), the fitted values against the truth and the held-out error.
``--bag``: the run is first made a robot's rosbag2 bag (joint_states at
500 Hz with jitter and drops, JointState commands, a segments sidecar: as
test/cli/test_commission_bag.py writes it, with rosbags) and ``commission``
reads the bag with its mapping flags. ``--ref COMMIT``: each repeat runs
``commission`` of that commit (a git worktree of it) and of this tree side by
side on the same recording; the last line gives each one's best wall time,
their ratio and whether the two fit.yaml files agree to every byte.
"""
import argparse
import json
import math
import os
import resource
import subprocess
import sys
import tempfile
import time

FACTORS = dict(mu_s=1.25, mu_k=0.8, stribeck_velocity=1.3)


def main():
    """Record once, commission ``--repeat`` times; print the figures."""
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[1])
    ap.add_argument('--repeat', type=int, default=1)
    ap.add_argument('--seed', type=int, default=11)
    ap.add_argument('--bag', action='store_true', help='commission a robot bag of the run')
    ap.add_argument('--ref', default='', help='a commit to time side by side with this tree')
    a = ap.parse_args()
    from leadscrew_sim import load_preset
    p0 = load_preset('tr12x3')
    truth = {n: getattr(p0, n) * f for n, f in FACTORS.items()}
    sensors = dict(encoder_counts=2 ** 16, encoder_noise=0.5 * 2 * math.pi / 2 ** 16,
                   scale_resolution=1e-6, scale_noise=5e-7, sensor_seed=a.seed)
    sets = [x for n, v in dict(truth, **sensors).items() for x in ('--set', f'{n}={v!r}')]
    cli = [sys.executable, '-m', 'leadscrew_sim.cli']
    with tempfile.TemporaryDirectory() as d:
        rec = os.path.join(d, 'run.mcap')
        subprocess.run(cli + ['simulate', '--preset', 'tr12x3', '--excite', 'commission', *sets,
                              '-q', '-o', rec], check=True, env=dict(os.environ))
        extra = []
        if a.bag:
            here = os.path.dirname(os.path.abspath(__file__))
            sys.path[:0] = [os.path.join(here, '..', 'test'),
                            os.path.join(here, '..', 'test', 'cli')]
            import test_commission_bag as T
            from pathlib import Path
            bag, side = os.path.join(d, 'robot_bag'), os.path.join(d, 'parts.json')
            T.write_robot_bag(Path(rec), Path(bag), Path(side))
            rec, extra = bag, ['--segments', side, *T.mapping()]
        print(f'command: leadscrew_sim commission RUN -o DIR {" ".join(extra)}  (RUN: '
              f'{"a robot bag of " if a.bag else ""}simulate --preset tr12x3 '
              f'--excite commission {" ".join(sets)})')
        trees = {'this tree': os.path.join(os.path.dirname(os.path.abspath(__file__)), '..')}
        if a.ref:
            ref = os.path.join(d, 'ref')
            subprocess.run(['git', '-C', trees['this tree'], 'worktree', 'add', '--detach', '-f',
                            ref, a.ref], check=True, capture_output=True)
            trees = {a.ref: ref, **trees}
        walls, fits = {t: [] for t in trees}, {}
        try:
            for k in range(a.repeat):
                for name, tree in trees.items():
                    out = os.path.join(d, f'out{k}_{len(walls[name])}_{name.replace(" ", "_")}')
                    env = dict(os.environ, PYTHONPATH=os.path.abspath(tree))
                    t0 = time.perf_counter()
                    c0 = resource.getrusage(resource.RUSAGE_CHILDREN)
                    subprocess.run(cli + ['commission', rec, '-o', out, *extra], check=True,
                                   env=env, cwd=tree)
                    wall = time.perf_counter() - t0
                    c1 = resource.getrusage(resource.RUSAGE_CHILDREN)
                    cpu = c1.ru_utime + c1.ru_stime - c0.ru_utime - c0.ru_stime
                    load = os.getloadavg()[0]
                    with open(os.path.join(out, 'report.json')) as fh:
                        r = json.load(fh)
                    with open(os.path.join(out, 'fit.yaml')) as fh:
                        fits.setdefault(fh.read(), []).append(name)
                    walls[name].append(wall)
                    stages = ', '.join(f'{n} {s:.2f}' for n, s in r['timings_s'].items())
                    print(f'run {k + 1} ({name}): {wall:.1f} s wall, {cpu:.1f} s CPU (process; '
                          f'load average {load:.1f}), stages [s]: {stages}', flush=True)
        finally:
            if a.ref:
                subprocess.run(['git', '-C', trees['this tree'], 'worktree', 'remove', '--force',
                                ref], capture_output=True)
        if a.ref:
            best = {t: min(w) for t, w in walls.items()}
            print('best wall [s]: ' + ', '.join(f'{t} {w:.1f}' for t, w in best.items()) +
                  f'; this tree / {a.ref} {best["this tree"] / best[a.ref]:.3f}; fit.yaml '
                  f'{"identical" if len(fits) == 1 else "DIFFERS"}')
        for row in r['sections']['identify']['parameters']:
            err = (row['value'] - truth[row['name']]) / truth[row['name']]
            print(f'  {row["name"]}: {row["value"]:.6g} (truth {truth[row["name"]]:.6g}, '
                  f'{err:+.2%}), 95 % [{row["lower"]:.6g}, {row["upper"]:.6g}]')
        h = r['sections']['twin']['held_out']
        print(f'  held-out (reversals): RMS {h["rms_um"]:.3g} um = {h["rms_over_noise"]:.3g} '
              f'noise, max {h["max_um"]:.3g} um; closed-loop floor {h.get("floor_um", 0):.3g} '
              f'um ({h.get("rms_over_floor", float("nan")):.3g} times)')


if __name__ == '__main__':
    main()
