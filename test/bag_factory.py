"""
Bags in ros2_control's layout, written by rosbags (an independent writer) from simulate runs.

A test runs ``leadscrew_sim simulate`` with its own secret parameter values,
decodes the run's ``axis/joint_states`` with mcap_ros2 (a reader we did not
write) and re-samples them into a rosbag2 bag as a robot records it:
``/joint_states`` of joint_state_broadcaster (two joints of the user's
names, epoch header stamps, irregular 2-10 ms intervals with drops), and the
commands as forward_command_controller (``std_msgs/Float64MultiArray``) or
joint_trajectory_controller (``trajectory_msgs/JointTrajectory``) receive
them, with a receipt latency. ``import bag_factory`` (test/ is on sys.path).
"""
import os
from pathlib import Path
import shutil

from helpers import cli_ok, NS
from mcap_ros2.reader import read_ros2_messages
import numpy as np
from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.typesys import get_typestore, Stores
import yaml

#: Epoch time of the bag's start [ns] (a wall clock, as a robot stamps).
EPOCH = 1_764_763_200_123_456_789
#: The robot's joint names.
SCREW, NUT = 'axis_screw_joint', 'axis_nut_joint'
STATES = '/joint_states'
#: The states topic of a ``simulate`` file (the node's name).
SIM_STATES = '/axis/joint_states'
FORWARD = '/forward_position_controller/commands'
TRAJECTORY = '/joint_trajectory_controller/joint_trajectory'
#: Receipt latency of the commands [ns]: their log time is their sending time plus this.
LATENCY = 400_000

TYPESTORE = get_typestore(Stores.ROS2_JAZZY)


def simulate(tmp, sets, position_csv, duration, name='sim.mcap'):
    """Run ``simulate`` with ``--set`` values and a nut position CSV; return the file."""
    out = Path(tmp) / name
    args = ['simulate', '--preset', 'tr12x3', '--duration', duration, '--position-csv',
            position_csv, '-o', out, '-q']
    for k, v in sets.items():
        args += ['--set', f'{k}={v}']
    cli_ok(*args)
    return out


def sim_states(path, topic=SIM_STATES):
    """Return (stamps [ns], position (n, 2), velocity (n, 2), effort (n, 2)) via mcap_ros2."""
    stamps, pos, vel, eff = [], [], [], []
    for m in read_ros2_messages(str(path), topics=[topic]):
        msg = m.ros_msg
        stamps.append(msg.header.stamp.sec * NS + msg.header.stamp.nanosec)
        pos.append(list(msg.position))
        vel.append(list(msg.velocity))
        eff.append(list(msg.effort))
    return (np.array(stamps, dtype=np.int64), np.array(pos), np.array(vel), np.array(eff))


def irregular(n_sim, seed, lo_ms=2, hi_ms=10, drop=0.05):
    """Return indices into a 1 kHz state series: intervals lo..hi ms, a share dropped."""
    rng = np.random.default_rng(seed)
    idx, i = [], 1
    while i < n_sim:
        if rng.random() >= drop:
            idx.append(i)
        i += int(rng.integers(lo_ms, hi_ms + 1))
    return np.array(idx)


def joint_state(stamp, names, pos, vel, eff):
    """Return a rosbags sensor_msgs/JointState."""
    T = TYPESTORE.types
    sec, nsec = divmod(int(stamp), NS)
    return T['sensor_msgs/msg/JointState'](
        header=T['std_msgs/msg/Header'](stamp=T['builtin_interfaces/msg/Time'](
            sec=sec, nanosec=nsec), frame_id=''),
        name=list(names), position=np.asarray(pos, dtype=float),
        velocity=np.asarray(vel, dtype=float), effort=np.asarray(eff, dtype=float))


def multi_array(values):
    """Return a rosbags std_msgs/Float64MultiArray with empty layout."""
    T = TYPESTORE.types
    return T['std_msgs/msg/Float64MultiArray'](
        layout=T['std_msgs/msg/MultiArrayLayout'](dim=[], data_offset=0),
        data=np.asarray(values, dtype=float))


def trajectory(stamp, names, points):
    """Return a rosbags JointTrajectory; points: (positions, velocities, time_from_start [ns])."""
    T = TYPESTORE.types
    sec, nsec = divmod(int(stamp), NS)
    pts = []
    for pos, vel, tfs in points:
        s, n = divmod(int(tfs), NS)
        pts.append(T['trajectory_msgs/msg/JointTrajectoryPoint'](
            positions=np.asarray(pos, dtype=float), velocities=np.asarray(vel, dtype=float),
            accelerations=np.zeros(0), effort=np.zeros(0),
            time_from_start=T['builtin_interfaces/msg/Duration'](sec=s, nanosec=n)))
    return T['trajectory_msgs/msg/JointTrajectory'](
        header=T['std_msgs/msg/Header'](stamp=T['builtin_interfaces/msg/Time'](
            sec=sec, nanosec=nsec), frame_id=''),
        joint_names=list(names), points=pts)


def write_bag(path, messages, compress=False):
    """
    Write a bag with rosbags: ``messages`` = [(log time [ns], topic, type, message)].

    Sorted by log time; ``compress``: zstd chunks (rosbags' storage compression).
    """
    writer = Writer(path, version=9, storage_plugin=StoragePlugin.MCAP)
    if compress:
        from rosbags.rosbag2.enums import CompressionFormat, CompressionMode
        writer.set_compression(CompressionMode.STORAGE, CompressionFormat.ZSTD)
    with writer:
        conns = {}
        for t, topic, mtype, msg in sorted(messages, key=lambda m: m[0]):
            if topic not in conns:
                conns[topic] = writer.add_connection(topic, mtype, typestore=TYPESTORE)
            writer.write(conns[topic], int(t), TYPESTORE.serialize_cdr(msg, mtype))
    return Path(path)


def split_bag(path, messages, at_ns):
    """
    Write a bag in two files, split at log time ``at_ns``: each file by rosbags, one metadata.

    rosbags writes one file per bag; the two halves are written as bags of
    their own and joined under one metadata.yaml listing both, as rosbag2's
    splitting leaves them (``<name>_0.mcap``, ``<name>_1.mcap``).
    """
    path = Path(path)
    path.mkdir()
    parts, infos = [], []
    for i, keep in enumerate((lambda t: t < at_ns, lambda t: t >= at_ns)):
        part = path.parent / f'{path.name}.part{i}'
        write_bag(part, [m for m in messages if keep(m[0])])
        info = yaml.safe_load((part / 'metadata.yaml').read_text())['rosbag2_bagfile_information']
        src = part / info['relative_file_paths'][0]
        dst = path / f'{path.name}_{i}.mcap'
        shutil.move(str(src), dst)
        infos.append(info)
        parts.append(dst.name)
        shutil.rmtree(part)
    meta = dict(infos[0])
    meta['relative_file_paths'] = parts
    meta['files'] = [dict(f['files'][0], path=p) for f, p in zip(infos, parts)]
    meta['message_count'] = sum(f['message_count'] for f in infos)
    (path / 'metadata.yaml').write_text(yaml.safe_dump({'rosbag2_bagfile_information': meta}))
    return path


def state_messages(stamps, pos, vel, eff, keep):
    """Return the bag messages of /joint_states: the kept sim states at EPOCH + their stamp."""
    out = []
    for i in keep:
        s = EPOCH + int(stamps[i])
        out.append((s + 150_000, STATES, 'sensor_msgs/msg/JointState',
                    joint_state(s, (SCREW, NUT), pos[i], vel[i], eff[i])))
    return out


def mcap_doctor(path):
    """Run ``mcap doctor`` on ``path``: (ran, ok, output); ran False without the CLI."""
    import subprocess
    from helpers import SHARED
    exe = SHARED / 'mcap-cli' / 'mcap'
    if not exe.exists():
        return False, True, ''
    r = subprocess.run([str(exe), 'doctor', str(path)], capture_output=True, text=True,
                       timeout=120, env=dict(os.environ))
    return True, r.returncode == 0, r.stdout + r.stderr


def strip_records(src, dst, drop=()):
    """
    Copy the messages of MCAP ``src`` into ``dst``, without its metadata records.

    As a ``ros2 bag record`` of the node leaves it: no parameters record, so no
    sensor seed and no sensor model (the mcap library's writer, not ours).
    The topics in ``drop`` are left out too (a bag that did not record them).
    """
    from mcap.reader import make_reader
    from mcap.writer import Writer
    with open(src, 'rb') as fi, open(dst, 'wb') as fo:
        w = Writer(fo)
        w.start(profile='ros2', library='test')
        schemas, chans = {}, {}
        for schema, ch, msg in make_reader(fi).iter_messages(log_time_order=False):
            if ch.topic in drop:
                continue
            if schema.id not in schemas:
                schemas[schema.id] = w.register_schema(schema.name, schema.encoding,
                                                       schema.data)
            if ch.id not in chans:
                chans[ch.id] = w.register_channel(ch.topic, ch.message_encoding,
                                                  schemas[schema.id], ch.metadata)
            w.add_message(chans[ch.id], msg.log_time, msg.data, msg.publish_time, msg.sequence)
        w.finish()
