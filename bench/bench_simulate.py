"""
Benchmark ``leadscrew_sim simulate`` against the bare model loop, in one run.

Run: .venv/bin/python bench/bench_simulate.py [--seconds 60] [--amplitude 0.4] [--profile]
Prints wall time and x-real-time of (a) the bare loop (LeadScrewModel.advance
tick by tick, same torque sequence), (b) the bare block kernel (model.run on
blocks of simulate's size, same torques) and (c) simulate (model, encoding
and MCAP recording of every default topic), the ratios of (c) to both and the
bytes per simulated second. The default sine of 0.4 N m at 0.5 Hz moves the
nut of the self-locking tr12x3 (a smaller one holds it still: no contact
changes, no sliding). --profile adds the top functions of simulate by cProfile.
"""
import argparse
import cProfile
import io
import math
import os
import pstats
import sys
import tempfile
import time

from leadscrew_sim import cli, LeadScrewModel, load_preset


def bare_loop(seconds, rate, amplitude, frequency):
    """Return the wall time [s] of the model loop alone."""
    m = LeadScrewModel(load_preset('tr12x3'), dt=round(1e9 / rate) / 1e9)
    m.advance(0.0)
    m.reset()
    n = int(round(seconds * rate))
    dt = 1.0 / rate
    w = 2 * math.pi * frequency
    t0 = time.perf_counter()
    for k in range(n):
        m.advance(amplitude * math.sin(w * k * dt))
    return time.perf_counter() - t0


def bare_blocks(seconds, rate, amplitude, frequency, block=1000):
    """Return the wall time [s] of the block kernel alone (model.run, as simulate calls it)."""
    m = LeadScrewModel(load_preset('tr12x3'), dt=round(1e9 / rate) / 1e9)
    m.run([0.0])
    m.reset()
    n = int(round(seconds * rate))
    dt = 1.0 / rate
    w = 2 * math.pi * frequency
    torques = [amplitude * math.sin(w * k * dt) for k in range(n)]
    t0 = time.perf_counter()
    for k in range(0, n, block):
        m.run(torques[k:k + block])
    return time.perf_counter() - t0


def main():
    """Run both and print the comparison."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[1])
    ap.add_argument('--seconds', type=float, default=60.0)
    ap.add_argument('--amplitude', type=float, default=0.4, help='sine torque [N m]')
    ap.add_argument('--profile', action='store_true')
    ap.add_argument('--sort', default='tottime', help='cProfile sort key for --profile')
    a = ap.parse_args()
    rate, amp, freq = 1000.0, a.amplitude, 0.5
    bare = bare_loop(a.seconds, rate, amp, freq)
    blocks = bare_blocks(a.seconds, rate, amp, freq)
    with tempfile.TemporaryDirectory() as d:
        out = os.path.join(d, 'bench.mcap')
        argv = ['simulate', '--duration', str(a.seconds), '--profile', 'sine', '--amplitude',
                str(amp), '--frequency', str(freq), '--output', out, '--quiet']
        prof = cProfile.Profile() if a.profile else None
        t0 = time.perf_counter()
        if prof:
            prof.enable()
        rc = cli.main(argv)
        if prof:
            prof.disable()
        wall = time.perf_counter() - t0
        size = os.path.getsize(out)
    if rc != 0:
        sys.exit(rc)
    print(f'default preset tr12x3, {a.seconds:g} s at {rate:g} Hz, sine {amp} N m {freq} Hz')
    print(f'bare model loop : {bare:8.3f} s wall  {a.seconds / bare:8.1f}x real time')
    print(f'bare block kernel: {blocks:7.3f} s wall  {a.seconds / blocks:8.1f}x real time')
    print(f'simulate (MCAP) : {wall:8.3f} s wall  {a.seconds / wall:8.1f}x real time')
    print(f'simulate / bare : {wall / bare:8.2f}')
    print(f'simulate / block kernel: {wall / blocks:5.2f}')
    print(f'file size       : {size} B = {size / a.seconds:.0f} B per simulated second')
    if prof:
        s = io.StringIO()
        pstats.Stats(prof, stream=s).sort_stats(a.sort).print_stats(25)
        print(s.getvalue())


if __name__ == '__main__':
    main()
