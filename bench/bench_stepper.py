"""
Benchmark the stepper's kernel cost per simulated millisecond against the servo presets.

Run: .venv/bin/python bench/bench_stepper.py [--seconds 4] [--repeats 7]

Each stepper preset runs beside the servo preset of its mechanics
(nema17_tr8x8 beside tr8x8, nema23_tr12x3 beside tr12x3) on the same position
commands (the nut along x0 + 10 mm sin(2 pi 0.5 Hz t), beyond the steppers'
top step rate, so they run at it; 'half': the sine whose top speed is half
that rate's; 1 kHz command rows, one compiled model.run call per repeat),
and holding still. Prints per pair the
substeps per step, the wall time per simulated ms (best of the repeats, the
runs of a pair interleaved) and the ratio stepper / servo.
"""
import argparse
import math
import time

import numpy as np

from leadscrew_sim import LeadScrewModel, load_preset
from leadscrew_sim.core.drive_modes import MODE_POSITION

PAIRS = (('nema17_tr8x8', 'tr8x8'), ('nema23_tr12x3', 'tr12x3'))


def rows(p, n, amplitude):
    """Return n position command rows of the nut along x0 + amplitude sin(2 pi 0.5 Hz t)."""
    m = LeadScrewModel(p)
    t = np.arange(n) * 1e-3
    theta = m.nut_to_motor(p.initial_position + amplitude * np.sin(math.pi * t))
    out = np.full((n, 4), math.nan)
    out[:, 0] = MODE_POSITION
    out[:, 1] = theta
    return out


def half_rate_amplitude(p):
    """Return the amplitude [m] of the 0.5 Hz sine whose top speed is half the top step rate's."""
    m = LeadScrewModel(p)
    x0 = p.initial_position
    rad_per_m = (m.nut_to_motor(x0 + 1e-4) - m.nut_to_motor(x0)) / 1e-4
    top = p.max_step_rate * p.step_angle / abs(rad_per_m)       # nut speed [m/s]
    return 0.5 * top / math.pi


def timed(p, cmds):
    """Return (wall seconds of one model.run over cmds, substeps per step)."""
    m = LeadScrewModel(p)
    t0 = time.perf_counter()
    m.run(None, commands=cmds)
    return time.perf_counter() - t0, m.nsub


def main():
    """Print the table."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[1])
    ap.add_argument('--seconds', type=float, default=4.0, help='simulated time per run [s]')
    ap.add_argument('--repeats', type=int, default=7)
    args = ap.parse_args()
    n = int(round(args.seconds / 1e-3))
    print(f'{"pair":<28} {"drive":<6} {"substeps":>8} {"servo us/ms":>12} '
          f'{"stepper us/ms":>14} {"ratio":>6}')
    for stepper, servo in PAIRS:
        ps, pv = load_preset(stepper), load_preset(servo)
        for drive, amp in (('move', 0.01), ('half', half_rate_amplitude(ps)), ('hold', 0.0)):
            cs, cv = rows(ps, n, amp), rows(pv, n, amp)
            timed(ps, cs[:10])
            timed(pv, cv[:10])
            best = {stepper: math.inf, servo: math.inf}
            nsub = {}
            for _ in range(args.repeats):
                for name, p, c in ((servo, pv, cv), (stepper, ps, cs)):
                    dt, nsub[name] = timed(p, c)
                    best[name] = min(best[name], dt)
            us_v = best[servo] / n * 1e6
            us_s = best[stepper] / n * 1e6
            print(f'{stepper + " / " + servo:<28} {drive:<6} '
                  f'{str(nsub[stepper]) + "/" + str(nsub[servo]):>8} {us_v:12.2f} '
                  f'{us_s:14.2f} {us_s / us_v:6.2f}', flush=True)


if __name__ == '__main__':
    main()
