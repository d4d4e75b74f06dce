"""
Time reading the mapped topics of a 10-minute rosbag2 bag at 500 Hz (issue: under 5 s).

Run: .venv/bin/python bench/bench_bag.py [--minutes 10] [--rate 500] [--repeat 3]

The bag is written by rosbags in ros2_control's layout, zstd chunks, split in
two files: ``/joint_states`` (two joints, position, velocity and effort,
epoch stamps with 0-0.2 ms jitter, 2 % dropped) at ``--rate``,
``/forward_position_controller/commands`` (Float64MultiArray) at 100 Hz, and
traffic the mapping does not read (``/camera/info``, 1 kB at 30 Hz;
``/diagnostics``-like strings at 10 Hz). Timed, best of ``--repeat``, each
in a fresh process so that no page cache of Python objects helps:

- ``open``: :func:`open_recording` of the bag without its messages
  (metadata.yaml, both files' summaries);
- ``mapped``: that plus reading the two mapped topics through the chunk
  indexes and decoding them (:class:`ForeignReplay` up to its grid, no
  re-simulation);
- ``all messages``: :func:`open_recording` with every message, for comparison.
"""
import argparse
import json
import os
import subprocess
import sys
import tempfile
import time

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(__file__), '..', 'test'))

EPOCH = 1_764_763_200_000_000_000
NS = 1_000_000_000

_CHILD = r'''
import json, sys, time
t = time.perf_counter()
from leadscrew_sim.offline.options import open_recording
from leadscrew_sim.offline.foreign.mapping import Mapping
from leadscrew_sim.offline.foreign.replay import ForeignReplay
from leadscrew_sim.core.presets import load_preset
imported = time.perf_counter() - t
what, bag = sys.argv[1], sys.argv[2]
t = time.perf_counter()
if what == 'open':
    rec = open_recording(bag, load_messages=False)
    n = 0
elif what == 'mapped':
    rec = open_recording(bag, load_messages=False)
    m = Mapping(command_topic='/forward_position_controller/commands', command_kind='position',
                command_index=1, screw_joint='axis_screw_joint', nut_joint='axis_nut_joint',
                command_delay=0.0)
    rep = ForeignReplay(m, rec, load_preset('tr12x3'))
    n = len(rep.states) + len(rep.commands.times)
else:
    rec = open_recording(bag)
    n = len(rec.messages)
print(json.dumps({'seconds': time.perf_counter() - t, 'messages': n, 'imports': imported}))
'''


def write_bag(path, minutes, rate):
    """Write the bag (two files) with rosbags; return the message count."""
    import bag_factory as B
    from rosbags.rosbag2.enums import CompressionFormat, CompressionMode
    from rosbags.rosbag2 import StoragePlugin, Writer
    rng = np.random.default_rng(7)
    T = B.TYPESTORE.types
    duration = int(minutes * 60 * NS)
    js = np.arange(0, duration, int(NS / rate))
    js = js[rng.random(len(js)) > 0.02]
    js = js + rng.integers(0, 200_000, len(js))         # stamp jitter, 0 .. 0.2 ms
    cmd = np.arange(0, duration, NS // 100)
    cam = np.arange(0, duration, NS // 30)
    diag = np.arange(0, duration, NS // 10)
    half = duration // 2
    os.makedirs(path)
    names, infos, count = [], [], 0
    for part, (a, b) in enumerate(((0, half), (half, duration))):
        sub = f'{path}.part{part}'
        w = Writer(sub, version=9, storage_plugin=StoragePlugin.MCAP)
        w.set_compression(CompressionMode.STORAGE, CompressionFormat.ZSTD)
        with w:
            c_js = w.add_connection('/joint_states', 'sensor_msgs/msg/JointState',
                                    typestore=B.TYPESTORE)
            c_cmd = w.add_connection('/forward_position_controller/commands',
                                     'std_msgs/msg/Float64MultiArray', typestore=B.TYPESTORE)
            c_cam = w.add_connection('/camera/info', 'std_msgs/msg/String',
                                     typestore=B.TYPESTORE)
            c_diag = w.add_connection('/diagnostics_text', 'std_msgs/msg/String',
                                      typestore=B.TYPESTORE)
            blob = B.TYPESTORE.serialize_cdr(T['std_msgs/msg/String'](data='x' * 1000),
                                             'std_msgs/msg/String')
            note = B.TYPESTORE.serialize_cdr(T['std_msgs/msg/String'](data='ok: axis'),
                                             'std_msgs/msg/String')
            events = []
            for t in js[(js >= a) & (js < b)]:
                x = 0.01 * np.sin(2 * np.pi * 0.2 * t / NS)
                events.append((EPOCH + int(t) + 150_000, c_js, bytes(B.TYPESTORE.serialize_cdr(
                    B.joint_state(EPOCH + int(t), (B.SCREW, B.NUT), [x * 2094, x],
                                  [0.0, 0.0], [0.0, 0.0]), 'sensor_msgs/msg/JointState'))))
            for t in cmd[(cmd >= a) & (cmd < b)]:
                x = 0.01 * np.sin(2 * np.pi * 0.2 * t / NS)
                events.append((EPOCH + int(t), c_cmd, bytes(B.TYPESTORE.serialize_cdr(
                    B.multi_array([0.0, x]), 'std_msgs/msg/Float64MultiArray'))))
            events += [(EPOCH + int(t), c_cam, blob) for t in cam[(cam >= a) & (cam < b)]]
            events += [(EPOCH + int(t), c_diag, note) for t in diag[(diag >= a) & (diag < b)]]
            events.sort(key=lambda e: e[0])
            for t, c, data in events:
                w.write(c, t, data)
            count += len(events)
        import yaml
        info = yaml.safe_load(open(os.path.join(sub, 'metadata.yaml')))
        info = info['rosbag2_bagfile_information']
        src = os.path.join(sub, info['relative_file_paths'][0])
        name = f'bag_{part}.mcap'
        os.rename(src, os.path.join(path, name))
        names.append(name)
        infos.append(info)
        os.remove(os.path.join(sub, 'metadata.yaml'))
        os.rmdir(sub)
    meta = dict(infos[0], relative_file_paths=names,
                message_count=sum(i['message_count'] for i in infos))
    meta['files'] = [dict(i['files'][0], path=n) for i, n in zip(infos, names)]
    with open(os.path.join(path, 'metadata.yaml'), 'w') as fh:
        yaml.safe_dump({'rosbag2_bagfile_information': meta}, fh)
    return count


def timed(what, bag):
    """Run one timing in a fresh process; return its result dict."""
    r = subprocess.run([sys.executable, '-c', _CHILD, what, bag], capture_output=True,
                       text=True, env=dict(os.environ), check=True)
    return json.loads(r.stdout)


def main():
    """Write the bag, time the reads, print the table."""
    ap = argparse.ArgumentParser()
    ap.add_argument('--minutes', type=float, default=10.0)
    ap.add_argument('--rate', type=float, default=500.0)
    ap.add_argument('--repeat', type=int, default=3)
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        bag = os.path.join(tmp, 'bag')
        t = time.perf_counter()
        n = write_bag(bag, args.minutes, args.rate)
        size = sum(os.path.getsize(os.path.join(bag, f)) for f in os.listdir(bag))
        print(f'bag: {args.minutes:g} min, /joint_states at {args.rate:g} Hz, {n} messages in '
              f'2 files, {size / 1e6:.1f} MB (zstd chunks); written in '
              f'{time.perf_counter() - t:.1f} s by rosbags')
        print(f'{"read":<14} {"best s":>8} {"runs s":>24} {"messages":>10}  (imports s)')
        for what in ('open', 'mapped', 'all messages'):
            runs = [timed(what.split()[0], bag) for _ in range(args.repeat)]
            secs = [r['seconds'] for r in runs]
            print(f'{what:<14} {min(secs):8.3f} {" ".join(f"{s:.3f}" for s in secs):>24} '
                  f'{runs[0]["messages"]:>10}  ({min(r["imports"] for r in runs):.2f})')


if __name__ == '__main__':
    main()
