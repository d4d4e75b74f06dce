"""
Find the highest update rate at which the node keeps simulated time locked to wall time.

Run: .venv/bin/python bench/bench_rate.py [--duration 60] [--rates 1000 2000 3000 ...]
(with AMENT_PREFIX_PATH and NUMBA_CACHE_DIR set as in the Makefile).

For each rate, one after the other: ``leadscrew_sim_node`` in realtime mode
with recording on runs for ``--duration`` s while this process subscribes to
``axis/joint_states`` and sends a torque every 100 ms (as bench_node.py). Locked
means the catch-up was never exhausted: zero overruns (skipped steps) over
the whole run, so simulated time advanced exactly with wall time. Prints,
per rate: achieved rate, late ticks and catch-up steps, overruns, CPU of
the node and of its recorder child, the subscriber's message rate.
"""
import argparse
import os
from pathlib import Path
import sys
import tempfile

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_node import isolate_ros_env, measure  # noqa: E402


def main():
    """Measure each rate and print a table."""
    ap = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    ap.add_argument('--duration', type=float, default=60.0)
    ap.add_argument('--rates', type=float, nargs='+', default=[1000, 2000, 3000, 4000, 5000])
    ap.add_argument('--preset', default='tr12x3')
    args = ap.parse_args()
    isolate_ros_env()
    tmp = Path(tempfile.mkdtemp(prefix='bench_rate_'))
    print(f'bench_rate: {args.duration:g} s per rate, preset {args.preset}, recording on; '
          f'{os.cpu_count()} CPUs; files in {tmp}', flush=True)
    rows = []
    for rate in args.rates:
        stats = tmp / f'node_{rate:g}.json'
        argv = [sys.executable, '-m', 'leadscrew_sim.node', '--ros-args',
                '-p', f'preset:={args.preset}', '-p', f'update_rate:={rate}',
                '-p', f'stats_file:={stats}', '-p', 'record:=true',
                '-p', f'record_dir:={tmp / f"runs_{rate:g}"}', '-p', 'command_timeout:=0.0']
        r = measure(argv, stats, args.duration, f'node {rate:g} Hz')
        s = r['stats']
        rows.append((rate, s['achieved_rate'], r['sub_rate'], s['late_ticks'],
                     s.get('catchup_steps', 0), s['overruns'], s.get('skipped_steps', 0),
                     100 * r['cpu'], 100 * r['child_cpu']))
        print(f'  {rate:g} Hz done: overruns {s["overruns"]}', flush=True)
    print(f'{"rate [Hz]":>10s}{"achieved":>10s}{"at sub":>10s}{"late":>7s}{"catchup":>9s}'
          f'{"overruns":>10s}{"skipped":>9s}{"CPU %":>7s}{"child %":>9s}  locked')
    for rate, ach, sub, late, cu, ov, sk, cpu, kcpu in rows:
        print(f'{rate:10g}{ach:10.2f}{sub:10.2f}{late:7d}{cu:9d}{ov:10d}{sk:9d}{cpu:7.1f}'
              f'{kcpu:9.1f}  {"yes" if ov == 0 else "no"}')
    locked = [r[0] for r in rows if r[5] == 0]
    print(f'highest locked rate of those tried: {max(locked):g} Hz' if locked else
          'no rate stayed locked')
    return 0


if __name__ == '__main__':
    sys.exit(main())
