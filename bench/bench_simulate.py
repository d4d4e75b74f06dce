"""
Benchmark ``leadscrew_sim simulate`` and ``resim`` against the bare block kernel, in one run.

Run: .venv/bin/python bench/bench_simulate.py [--seconds 60] [--excite iso230] [--repeat 3]

The input is an identification profile through the servo drive (default
``iso230``: ISO 230-2 bidirectional positioning in position mode, the nut
travelling over +-96 mm of the tr12x3 stroke with reversals and dwells), cut
to ``--seconds``. Printed side by side, each the best of ``--repeat`` runs:

- the bare block kernel: ``model.run`` on blocks of simulate's size with the
  very command rows simulate hands the drive (CommandHold.take_series);
- ``simulate`` writing every default topic (lz4, zstd and uncompressed
  chunks), in-process and warmed up; its start-up (parameters, robot
  description, file) is the time of a one-tick run, subtracted for the
  loop-only figure the ratios use;
- ``resim`` of the lz4 file (reading, re-simulating, writing, comparing),
  start-up likewise subtracted.

The ratios to the bare block kernel and the x-real-time figures are printed,
with the bytes per simulated second.
"""
import argparse
import os
import sys
import tempfile
import time

import numpy as np

from leadscrew_sim import cli, LeadScrewModel, load_preset
from leadscrew_sim.offline.simulate.run import BLOCK_TICKS
from leadscrew_sim.core.commands import CommandHold, NutMap
from leadscrew_sim.analysis.excitation.profiles import make_profile


def bare_blocks(seconds, rate, excite):
    """Return the wall time [s] of model.run on the profile's command rows, block by block."""
    params = load_preset('tr12x3')
    m = LeadScrewModel(params, dt=round(1e9 / rate) / 1e9)
    m.run([0.0])
    m.reset()
    prof = make_profile(excite, params)
    n = int(round(seconds * rate))
    t_ns = np.arange(n, dtype=np.int64) * int(round(1e9 / rate))
    hold = CommandHold('', 0.0, NutMap.of_model(m), params=params)
    rows = hold.take_series(prof.topic, prof.values(t_ns / 1e9), t_ns)
    forces = np.zeros(BLOCK_TICKS)
    t0 = time.perf_counter()
    for k in range(0, n, BLOCK_TICKS):
        block = rows[k:k + BLOCK_TICKS]
        m.run(None, forces[:len(block)], commands=block)
    return time.perf_counter() - t0


def timed(argv):
    """
    Return the wall time [s] of one in-process ``leadscrew_sim`` call (output hidden).

    The output file (after ``-o``) is removed first, outside the timing, so every run
    writes a new file, as the runs of a sweep do: rewriting a file in place costs the
    file system the freeing of its old blocks and, at close, a forced writeback
    (ext4 does that for a file truncated and written again).
    """
    path = argv[argv.index('-o') + 1]
    if os.path.exists(path):
        os.unlink(path)
    out = sys.stdout
    sys.stdout = open(os.devnull, 'w')
    try:
        t0 = time.perf_counter()
        rc = cli.main(argv)
        wall = time.perf_counter() - t0
    finally:
        sys.stdout.close()
        sys.stdout = out
    if rc != 0:
        sys.exit(rc)
    return wall


def main():
    """Run the kernel, simulate and resim side by side and print the comparison."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[1])
    ap.add_argument('--seconds', type=float, default=60.0, help='simulated time [s]')
    ap.add_argument('--excite', default='iso230', help='the identification profile')
    ap.add_argument('--repeat', type=int, default=3, help='runs of each; the best counts')
    a = ap.parse_args()
    rate, s = 1000.0, a.seconds
    with tempfile.TemporaryDirectory() as d:
        def sim(duration, compression, out='sim.mcap'):
            return timed(['simulate', '--excite', a.excite, '--duration', str(duration),
                          '--compression', compression, '-q', '-o', os.path.join(d, out)])

        def resim(name):
            return timed(['resim', os.path.join(d, name), '-q', '-o',
                          os.path.join(d, 'resim.mcap')])

        sim(0.001, 'lz4')                                   # imports, compilation
        best = {}
        for _ in range(a.repeat):                           # interleaved: same conditions
            for key, fn in (('kernel', lambda: bare_blocks(s, rate, a.excite)),
                            ('start', lambda: sim(0.001, 'lz4', 'tiny.mcap')),
                            ('lz4', lambda: sim(s, 'lz4', 'lz4.mcap')),
                            ('zstd', lambda: sim(s, 'zstd', 'zstd.mcap')),
                            ('none', lambda: sim(s, 'none', 'none.mcap')),
                            ('resim_start', lambda: resim('tiny.mcap')),
                            ('resim', lambda: resim('lz4.mcap'))):
                best[key] = min(best.get(key, float('inf')), fn())
        sizes = {c: os.path.getsize(os.path.join(d, f'{c}.mcap')) for c in ('lz4', 'zstd', 'none')}
    k = best['kernel']
    print(f'tr12x3 at {rate:g} Hz, --excite {a.excite} for {s:g} s, best of {a.repeat}')
    print(f'{"run":<28} {"wall [s]":>9} {"x real time":>12} {"/ kernel":>9} {"B per sim s":>12}')
    print(f'{"bare block kernel":<28} {k:9.4f} {s / k:12.1f} {1.0:9.2f}')
    for c in ('lz4', 'zstd', 'none'):
        loop = best[c] - best['start']
        print(f'{"simulate " + (c + " (default)" if c == "lz4" else c) + " loop":<28} '
              f'{loop:9.4f} {s / loop:12.1f} {loop / k:9.2f} {sizes[c] / s:12.0f}')
    print(f'{"simulate lz4 with start-up":<28} {best["lz4"]:9.4f} {s / best["lz4"]:12.1f} '
          f'{best["lz4"] / k:9.2f}')
    loop = best['resim'] - best['resim_start']
    print(f'{"resim (lz4 file) loop":<28} {loop:9.4f} {s / loop:12.1f} {loop / k:9.2f}')
    print(f'start-up: simulate {best["start"]:.4f} s, resim {best["resim_start"]:.4f} s')


if __name__ == '__main__':
    main()
