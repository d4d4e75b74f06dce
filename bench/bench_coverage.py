"""
Coverage of ``leadscrew_sim identify``'s 95 % intervals on recordings with real sensors.

Run: .venv/bin/python bench/bench_coverage.py [--seeds 3] [--profiles sweep,breakaway,..]
[--withheld]

Each profile is recorded by ``simulate`` on tr12x3 with the truth of
``test/cli/test_identify_real_sensors.py`` (mu_s 0.235, mu_k 0.128, Stribeck
velocity 1.15 mm/s; the fit starts at the preset's 0.2, 0.15, 1 mm/s) and its
real sensors (a 16-bit encoder with half a count of noise, a 1 um scale with
0.25 um of noise), with ``--seeds`` sensor seeds (7, 11, 15, ..): the
``sweep`` (velocity commands), ``breakaway`` (torque ramps), ``reversals``
(position targets) and ``commission`` (those three and a velocity chirp,
one after the other, each on its own command topic) excite profiles on the
vertical axis and that test's zero-order-hold torque steps from rest on the
horizontal one. ``identify`` fits mu_s, mu_k and the Stribeck velocity; a
row per recording gives each error, its 95 % half-width and whether the
interval holds the truth ('-' not identified), and the wall time; the last
line the share of the identified intervals that hold the truth.
"""
import argparse
import importlib
from pathlib import Path
import sys
import tempfile
import time

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent / 'test'))
sys.path.insert(0, str(HERE.parent / 'test' / 'cli'))
import test_identify_real_sensors as R  # noqa: E402  (the test's truth, sensors, profiles)
from bag_factory import strip_records  # noqa: E402  (a copy without the parameters record)

from leadscrew_sim import cli  # noqa: E402, I100
from leadscrew_sim.offline.identify.run import fit_recording  # noqa: E402

NAMES = ('mu_s', 'mu_k', 'stribeck_velocity')


def _profile(tmp, name):
    """Return simulate's options of profile ``name`` (and whether the axis is horizontal)."""
    if name == 'torque_steps':
        return R.PROFILES[name](tmp), True
    return ['--excite', name], False


def run_case(tmp, name, seed, withheld=False):
    """Record and fit one profile with one sensor seed; return (row text, holds, count)."""
    opts, horizontal = _profile(tmp, name)
    rec = tmp / f'{name}_{seed}.mcap'
    sensors = dict(R.REAL, sensor_seed=seed)
    cli.main(['simulate', '--preset', 'tr12x3', *map(str, opts), *R._sets(R.TRUTH),
              *R._sets(sensors), '-q', '-o', str(rec)])
    if withheld:
        strip_records(rec, tmp / f'{name}_{seed}_bare.mcap')
        rec = tmp / f'{name}_{seed}_bare.mcap'
    main = importlib.import_module('leadscrew_sim.cli.main')
    extra = R._sets(R.HORIZONTAL) if horizontal else []
    args = main.build_parser().parse_args(['identify', str(rec), '--preset', 'tr12x3',
                                           '--fit', ','.join(NAMES), *extra])
    t = time.perf_counter()
    out = fit_recording(args)
    wall = time.perf_counter() - t
    res, cells, holds, count = out['res'], [], 0, 0
    for n in NAMES:
        vd, v, truth = res.verdict(n), res.value(n), R.TRUTH[n]
        if not vd.identified:
            cells.append(f'{100 * (v - truth) / truth:+.2f} % (not identified)'
                         if vd.fitted else 'not identifiable')
            continue
        ok = vd.lower <= truth <= vd.upper
        holds, count = holds + ok, count + 1
        half = 50.0 * (vd.upper - vd.lower) / v
        cells.append(f'{100 * (v - truth) / truth:+.4f} % (+-{half:.3g} %){"" if ok else " MISS"}')
    return f'| {name} | {seed} | ' + ' | '.join(cells) + f' | {wall:.0f} s |', holds, count


def main():
    """Print the coverage table."""
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[1])
    ap.add_argument('--seeds', type=int, default=3, help='sensor seeds per profile (7, 11, ..)')
    ap.add_argument('--profiles', default='sweep,breakaway,reversals,torque_steps,commission')
    ap.add_argument('--withheld', action='store_true',
                    help='fit copies without the parameters record (no sensor seed or model)')
    a = ap.parse_args()
    seeds = [7 + 4 * i for i in range(a.seeds)]
    print('| profile | seed | mu_s | mu_k | Stribeck velocity | wall |')
    print('|---|---|---|---|---|---|')
    holds = count = 0
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory() as d:
        for name in a.profiles.split(','):
            for seed in seeds:
                row, h, c = run_case(Path(d), name, seed, a.withheld)
                holds, count = holds + h, count + c
                print(row, flush=True)
    share = f'{100 * holds / count:.0f} %' if count else '-'
    print(f'\n{holds} of {count} identified 95 % intervals hold the truth ({share}); '
          f'{time.perf_counter() - t0:.0f} s in all')


if __name__ == '__main__':
    main()
