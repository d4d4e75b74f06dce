"""
Soak the node: realtime 1 kHz with recording and split files, for a long time.

Run (not in CI): .venv/bin/python bench/soak.py --duration 3600 --split 300
(with AMENT_PREFIX_PATH and NUMBA_CACHE_DIR set as in the Makefile).
Reports the node's RSS at start (after warm-up) and end, the largest tick
lateness and the overruns from its diagnostics, the files written with their
sizes, and whether the joint_states count in the files equals the steps taken.
"""
import argparse
import os
import re
from pathlib import Path
import signal
import subprocess
import sys
import tempfile
import time


def rss_kib(pid):
    """Return the resident set size of a process [KiB]."""
    for line in Path(f'/proc/{pid}/status').read_text().splitlines():
        if line.startswith('VmRSS:'):
            return int(line.split()[1])
    return 0


def child_rss_kib(pid):
    """Return the summed RSS of a process's children (the recorder) [KiB]."""
    total = 0
    for task in Path(f'/proc/{pid}/task').glob('*'):
        try:
            kids = [int(c) for c in (task / 'children').read_text().split()]
        except OSError:
            continue
        total += sum(rss_kib(k) for k in kids)
    return total


def main():
    """Run the soak and print the figures."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[1])
    ap.add_argument('--duration', type=float, default=3600.0, help='seconds')
    ap.add_argument('--split', type=float, default=300.0, help='file split [s]')
    ap.add_argument('--warmup', type=float, default=20.0, help='seconds before the first RSS')
    args = ap.parse_args()
    os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
    os.environ.setdefault('ROS_DOMAIN_ID', '77')
    import rclpy
    from diagnostic_msgs.msg import DiagnosticArray

    out = Path(tempfile.mkdtemp(prefix='soak_'))
    log = open(out / 'node.log', 'wb')
    node = subprocess.Popen(
        [sys.executable, '-m', 'leadscrew_sim.node', '--ros-args', '-p', 'preset:=tr12x3',
         '-p', f'record_dir:={out}', '-p', f'record_split_seconds:={args.split}'],
        stdout=log, stderr=subprocess.STDOUT)
    rclpy.init()
    sub_node = rclpy.create_node('soak_monitor')
    diag = {}

    def on_diag(msg):
        for status in msg.status:
            diag.update({kv.key: kv.value for kv in status.values})

    sub_node.create_subscription(DiagnosticArray, 'diagnostics', on_diag, 10)
    t0 = time.monotonic()
    worst_max_us = 0.0
    rss0 = crss0 = None
    while time.monotonic() - t0 < args.duration and node.poll() is None:
        rclpy.spin_once(sub_node, timeout_sec=0.5)
        if rss0 is None and time.monotonic() - t0 > args.warmup:
            rss0, crss0 = rss_kib(node.pid), child_rss_kib(node.pid)
        if diag.get('lateness_max_us'):
            worst_max_us = max(worst_max_us, float(diag['lateness_max_us']))
    rss1, crss1 = rss_kib(node.pid), child_rss_kib(node.pid)
    last = dict(diag)
    node.send_signal(signal.SIGINT)
    node.wait(timeout=60)
    sub_node.destroy_node()
    rclpy.shutdown()

    from mcap.reader import make_reader
    files = sorted(out.glob('*.mcap'))
    js = 0
    for f in files:
        with open(f, 'rb') as fh:
            stats = make_reader(fh).get_summary()
            chans = {c.id: c.topic for c in stats.channels.values()}
            js += sum(n for cid, n in stats.statistics.channel_message_counts.items()
                      if chans[cid].endswith('joint_states'))
    print(f'soak: {args.duration:.0f} s at 1 kHz, split every {args.split:.0f} s, dir {out}')
    print(f'RSS after warm-up {rss0} KiB, at end {rss1} KiB, growth '
          f'{100.0 * (rss1 - rss0) / rss0:.1f} %' if rss0 else f'RSS at end {rss1} KiB')
    if rss0 and crss0:
        print(f'recorder child RSS after warm-up {crss0} KiB, at end {crss1} KiB, growth '
              f'{100.0 * (crss1 - crss0) / crss0:.1f} %')
    print(f'overruns {last.get("overruns")}, late ticks {last.get("late_ticks")}, largest '
          f'per-window max lateness {worst_max_us:.0f} us, rejected '
          f'{last.get("rejected_commands")}, recording error {last.get("recording_error")!r}')
    print(f'files {len(files)}: ' + ', '.join(f'{f.stat().st_size / 1e6:.1f} MB' for f in files))
    log.close()
    steps = re.findall(r'stopped after (\d+) steps', (out / 'node.log').read_text())
    print(f'joint_states in files {js}; steps taken by the node '
          f'{steps[-1] if steps else "unknown"} (equal: nothing lost)')


if __name__ == '__main__':
    main()
