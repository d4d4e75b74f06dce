"""
Measure a cold (empty numba cache) and a warm start: to the first axis/joint_states, and simulate.

Run: .venv/bin/python bench/bench_start.py [--repeat 2]
(with AMENT_PREFIX_PATH set as in the Makefile). For each of a cold start (a
new, empty NUMBA_CACHE_DIR: the kernel is compiled) and a warm one (the same
directory again: the kernel is loaded), it prints the wall time from starting
the node process to the first ``axis/joint_states`` message a subscriber in this
process receives, and the wall time of ``leadscrew_sim simulate --duration 0.1``
from start to exit.
"""
import argparse
import os
from pathlib import Path
import shutil
import subprocess
import sys
import tempfile
import time


def first_joint_states(env, timeout=300.0):
    """Start the node; return the seconds until the first axis/joint_states arrives here."""
    import rclpy
    from sensor_msgs.msg import JointState
    got = []
    node = rclpy.create_node('bench_start')
    node.create_subscription(JointState, 'axis/joint_states', lambda m: got.append(1), 10)
    t0 = time.monotonic()
    proc = subprocess.Popen([sys.executable, '-m', 'leadscrew_sim.node', '--ros-args', '-p',
                             'record:=false'], env=env, stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL)
    try:
        while not got and time.monotonic() - t0 < timeout:
            rclpy.spin_once(node, timeout_sec=0.05)
        return time.monotonic() - t0 if got else float('nan')
    finally:
        proc.terminate()
        proc.wait(timeout=30)
        node.destroy_node()


def simulate_wall(env, out):
    """Return the wall time [s] of a 0.1 s simulate, from process start to exit."""
    t0 = time.monotonic()
    subprocess.run([sys.executable, '-m', 'leadscrew_sim.cli', 'simulate', '--duration', '0.1',
                    '-q', '-o', str(out)], env=env, check=True, capture_output=True)
    return time.monotonic() - t0


def main():
    """Print cold and warm start figures."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[1])
    ap.add_argument('--repeat', type=int, default=2, help='cold/warm pairs')
    args = ap.parse_args()
    os.environ.setdefault('ROS_DOMAIN_ID', '78')
    os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
    import rclpy
    rclpy.init()
    tmp = Path(tempfile.mkdtemp(prefix='bench_start_'))
    print(f'{"run":<6} {"cache":<5} {"first joint_states [s]":>24} {"simulate 0.1 s [s]":>20}')
    try:
        for i in range(args.repeat):
            cache = tmp / f'cache{i}'
            for label in ('cold', 'warm'):
                if label == 'cold':
                    shutil.rmtree(cache, ignore_errors=True)
                env = dict(os.environ, NUMBA_CACHE_DIR=str(cache))
                js = first_joint_states(env)
                if label == 'cold':
                    shutil.rmtree(cache, ignore_errors=True)
                sim = simulate_wall(env, tmp / 'a.mcap')
                print(f'{i:<6} {label:<5} {js:24.2f} {sim:20.2f}', flush=True)
    finally:
        rclpy.shutdown()
        shutil.rmtree(tmp, ignore_errors=True)


if __name__ == '__main__':
    main()
