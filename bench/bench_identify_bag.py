"""
Time ``identify`` of a 60 s ros2_control bag of a velocity-controlled axis (issue: < 30 s).

Run: .venv/bin/python bench/bench_identify_bag.py [--seconds 60] [--seed 5] [--fit mu_s,mu_k]

The bag is the yardstick test's (``test/offline/test_identify_yardstick.py``),
made longer: ``simulate`` of tr12x3 with that test's secret friction (mu_s
0.23, mu_k 0.17), a 16-bit encoder with noise and a 1 um scale with noise,
commanded by forward_velocity_controller Float64MultiArray commands at 100 Hz;
written with rosbags in ros2_control's layout, joint states at irregular 2-10
ms stamps with drops, no sensor seed and no parameter record. The profile
repeats, every 4 s, moves out and back at a speed that changes from one
repetition to the next (4 .. 14 mm/s, with a 1.5 Hz ripple), each followed
by a rest. ``identify`` then runs as a subprocess with the mapping flags;
printed: its wall and CPU time, the load average, the re-simulations, and
the fitted values against the truth.
"""
import argparse
import os
from pathlib import Path
import resource
import subprocess
import sys
import tempfile
import time

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path[:0] = [str(HERE.parent / 'test'), str(HERE.parent / 'test' / 'offline')]
import bag_factory as B  # noqa: E402
import test_identify_yardstick as Y  # noqa: E402  (the bag's sensors, truth and layout)


def velocity(t):
    """Return the commanded nut velocity [m/s] at times ``t`` [s]: out and back every 4 s."""
    rep, u = np.floor(t / 4.0), np.mod(t, 4.0)
    speed = 0.004 + 0.001 * np.mod(rep * 7, 11)
    v = np.where((u > 0.3) & (u < 1.3), speed, np.where((u > 1.8) & (u < 2.8), -speed, 0.0))
    return v * (1 + 0.3 * np.sin(2 * np.pi * 1.5 * t))


def write_bag(tmp, seconds, seed):
    """Write the bag; return (its path, the command topic, the command's index)."""
    _flag, topic, index = Y.KINDS['velocity']
    t = np.arange(0.0, seconds, 0.01)
    col = velocity(t)
    csv = tmp / 'velocity.csv'
    csv.write_text(''.join(f'{a:.6f},{float(b)!r}\n' for a, b in zip(t, col)))
    out = tmp / 'velocity.mcap'
    args = [sys.executable, '-m', 'leadscrew_sim.cli', 'simulate', '--preset', 'tr12x3',
            '--duration', str(seconds), '--velocity-csv', str(csv), '-o', str(out), '-q']
    for k, v in {**Y.SENSORS, **Y.SECRET, 'sensor_seed': seed}.items():
        args += ['--set', f'{k}={v}']
    subprocess.run(args, check=True)
    stamps, pos, vel, eff = B.sim_states(out)
    msgs = B.state_messages(stamps, pos, vel, eff, B.irregular(len(stamps), seed))
    for a, b in zip(t, col):
        vals = [0.0, 0.0]
        vals[index] = b
        msgs.append((B.EPOCH + int(round(a * B.NS)) + B.LATENCY, topic,
                     'std_msgs/msg/Float64MultiArray', B.multi_array(vals)))
    return B.write_bag(tmp / 'velocity_bag', msgs), topic, index


def main():
    """Write the bag once, identify it ``--repeat`` times; print the figures."""
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[1])
    ap.add_argument('--seconds', type=float, default=60.0)
    ap.add_argument('--seed', type=int, default=5)
    ap.add_argument('--fit', default='mu_s,mu_k')
    ap.add_argument('--repeat', type=int, default=1)
    a = ap.parse_args()
    with tempfile.TemporaryDirectory() as d:
        bag, topic, index = write_bag(Path(d), a.seconds, a.seed)
        cmd = ['identify', str(bag), '--preset', 'tr12x3', '--fit', a.fit,
               '--state-topic', B.STATES, '--screw-joint', B.SCREW, '--nut-joint', B.NUT,
               '--command-topic', topic, '--command-index', str(index)]
        print('command: leadscrew_sim ' + ' '.join(cmd).replace(str(bag), 'BAG') +
              f'  (BAG: {a.seconds:g} s, velocity commands at 100 Hz, states every 2-10 ms)')
        for k in range(a.repeat):
            t0 = time.perf_counter()
            c0 = resource.getrusage(resource.RUSAGE_CHILDREN)
            r = subprocess.run([sys.executable, '-m', 'leadscrew_sim.cli', *cmd],
                               capture_output=True, text=True, env=dict(os.environ))
            wall = time.perf_counter() - t0
            c1 = resource.getrusage(resource.RUSAGE_CHILDREN)
            cpu = c1.ru_utime + c1.ru_stime - c0.ru_utime - c0.ru_stime
            if r.returncode:
                print(r.stdout + r.stderr)
                raise SystemExit(r.returncode)
            print(f'run {k + 1}: {wall:.1f} s wall, {cpu:.1f} s CPU (load average '
                  f'{os.getloadavg()[0]:.1f})', flush=True)
        for line in r.stdout.splitlines():
            name = line.split(' ')[0]
            if name in Y.SECRET or 're-simulations' in line or 'rms/sigma' in line \
                    or line.startswith(('screw_angle', 'nut_position', 'motor_torque')):
                print('  ' + line + (f'   (truth {Y.SECRET[name]})' if name in Y.SECRET
                                     else ''))


if __name__ == '__main__':
    main()
