"""
``play RUN --foxglove PORT``: a recording served to Foxglove with its timing, without ROS.

The player runs as a subprocess in which rclpy cannot be imported; the test's
own protocol client (test/foxglove_client.py) receives the messages and the
mcap library reads the file independently: the same bytes, the log times as
timestamps, spread over the recorded duration divided by the speed factor.
"""
import os
import socket
import subprocess
import sys
import time

from foxglove_client import FoxgloveClient, free_port
from helpers import cli_ok
from mcap.reader import make_reader
import pytest

#: The player with rclpy made unimportable (``sys.modules['rclpy'] = None``).
NO_ROS = ("import sys; sys.modules['rclpy'] = None; "
          "from leadscrew_sim.cli.main import main; sys.exit(main(sys.argv[1:]))")


@pytest.mark.timeout(60)
def test_play_foxglove_serves_recording_with_its_timing(tmp_path):
    run = tmp_path / 'run.mcap'
    cli_ok('simulate', '--preset', 'tr12x3', '--profile', 'move', '--target', '0.002',
           '--duration', '0.5', '-o', run)
    with open(run, 'rb') as fh:
        reader = make_reader(fh)
        recorded = {}
        for _schema, channel, message in reader.iter_messages():
            recorded.setdefault(channel.topic, []).append((message.log_time, message.data))
    port = free_port()
    log = open(tmp_path / 'play.log', 'wb')
    proc = subprocess.Popen(
        [sys.executable, '-c', NO_ROS, 'play', str(run), '--foxglove', str(port),
         '--speed-factor', '0.5', '--wait-subscribers', '2', '--wait-timeout', '30'],
        stdout=log, stderr=subprocess.STDOUT, env=dict(os.environ))
    try:
        c = FoxgloveClient(port, timeout=40.0, proc=proc)
        assert c.wait_channels(['/axis/joint_states', '/axis/robot_description'])
        assert c.channels['/axis/joint_states']['encoding'] == 'cdr'
        js = c.subscribe('/axis/joint_states')
        desc = c.subscribe('/axis/robot_description')
        arrivals = []

        def got_all():
            if c.data[js] and (not arrivals or arrivals[-1][1] != len(c.data[js])):
                arrivals.append((time.monotonic(), len(c.data[js])))
            return len(c.data[js]) >= len(recorded['/axis/joint_states'])
        assert c.poll_until(got_all, 30.0), (len(c.data[js]), len(recorded['/axis/joint_states']))
        assert proc.wait(timeout=20) == 0, (tmp_path / 'play.log').read_text()
    finally:
        if proc.poll() is None:
            proc.kill()
        log.close()
    out = (tmp_path / 'play.log').read_text()
    # The same bytes with the log times as the messageData timestamps.
    assert c.data[js] == recorded['/axis/joint_states']
    assert c.data[desc][0][1] == recorded['/axis/robot_description'][0][1]
    # Original timing at half speed: 0.5 s of recording over about 1 s.
    span = arrivals[-1][0] - arrivals[0][0]
    t = [lt for lt, _d in recorded['/axis/joint_states']]
    assert abs(span - 2 * (t[-1] - t[0]) / 1e9) < 0.25, span
    assert 'served' in out, out


@pytest.mark.timeout(60)
@pytest.mark.parametrize('storage', ['mcap', 'sqlite3'])
def test_play_foxglove_serves_a_rosbag2_bag(tmp_path, storage):
    """A bag written by rosbags: every message's bytes and log time reach the client."""
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore
    ts = get_typestore(Stores.ROS2_JAZZY)
    JointState, Header, Time = (ts.types[t] for t in (
        'sensor_msgs/msg/JointState', 'std_msgs/msg/Header', 'builtin_interfaces/msg/Time'))
    import numpy as np
    t0 = 1_700_000_000 * 10**9
    sent = []
    with Writer(tmp_path / 'bag', version=9, storage_plugin=getattr(
            StoragePlugin, storage.upper())) as w:
        conn = w.add_connection('/joint_states', 'sensor_msgs/msg/JointState', typestore=ts)
        for i in range(100):
            t = t0 + i * 2_000_000
            msg = JointState(header=Header(stamp=Time(sec=t // 10**9, nanosec=t % 10**9),
                                           frame_id=''), name=['screw_joint'],
                             position=np.array([i * 0.01]), velocity=np.array([]),
                             effort=np.array([]))
            data = bytes(ts.serialize_cdr(msg, 'sensor_msgs/msg/JointState'))
            w.write(conn, t, data)
            sent.append((t, data))
    port = free_port()
    proc = subprocess.Popen(
        [sys.executable, '-c', NO_ROS, 'play', str(tmp_path / 'bag'), '--foxglove', str(port),
         '--wait-subscribers', '1', '--wait-timeout', '30'],
        stdout=subprocess.PIPE, stderr=subprocess.STDOUT, env=dict(os.environ))
    try:
        try:
            c = FoxgloveClient(port, timeout=40.0, proc=proc)
        except OSError:
            proc.kill()
            raise AssertionError(proc.stdout.read()) from None
        assert c.wait_channels(['/joint_states'])
        assert c.channels['/joint_states']['schemaName'] == 'sensor_msgs/msg/JointState'
        sub = c.subscribe('/joint_states')
        assert c.poll_until(lambda: len(c.data[sub]) >= len(sent), 20.0), len(c.data[sub])
        assert proc.wait(timeout=20) == 0, proc.stdout.read()
    finally:
        if proc.poll() is None:
            proc.kill()
    assert c.data[sub] == sent


def test_play_foxglove_bad_port_and_port_in_use(tmp_path):
    run = tmp_path / 'run.mcap'
    cli_ok('simulate', '--preset', 'tr12x3', '--duration', '0.05', '-o', run)

    def play(port):
        return subprocess.run([sys.executable, '-m', 'leadscrew_sim.cli', 'play', str(run),
                               '--foxglove', str(port), '--wait-subscribers', '0'],
                              capture_output=True, text=True, timeout=60, env=dict(os.environ))
    out = play(70000)
    assert out.returncode == 2 and out.stderr.count('\n') == 1, out.stderr
    assert '--foxglove 70000' in out.stderr and '1-65535' in out.stderr
    with socket.socket() as taken:
        taken.bind(('127.0.0.1', 0))
        taken.listen(1)
        port = taken.getsockname()[1]
        out = play(port)
    assert out.returncode == 2 and out.stderr.count('\n') == 1, out.stderr
    assert out.stderr.startswith('leadscrew_sim: error: ') and str(port) in out.stderr
