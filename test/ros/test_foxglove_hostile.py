"""
The live view against bad clients, each counted in ``diagnostics`` while the node keeps its rate.

The cases: garbage frames, unknown channels, oversized messages, a client
that never reads, a port in use.

The clients are the test's own (test/foxglove_client.py, from the published
protocol); rosbags decodes the diagnostics.
"""
import json
import socket
import struct
import subprocess
import sys
import time

from foxglove_client import FoxgloveClient, free_port, SUBPROTOCOLS
from helpers import start_node
import pytest
from rosbags.typesys import Stores, get_typestore
import websocket

TS = get_typestore(Stores.ROS2_JAZZY)


def diagnostics(client, sub):
    """Return the decoded DiagnosticArrays of a subscription as [{key: value}]."""
    return [{kv.key: kv.value for kv in
             TS.deserialize_cdr(p, 'diagnostic_msgs/msg/DiagnosticArray').status[0].values}
            for _t, p in client.data[sub]]


@pytest.mark.timeout(60)
def test_bad_clients_counted_and_rate_holds(run_exe):
    port = free_port()
    proc = start_node(run_exe, f'foxglove_port:={port}')
    watch = FoxgloveClient(port, timeout=60.0, proc=proc)
    assert watch.wait_channels(['/diagnostics', '/axis/joint_states']), proc.output()
    diag = watch.subscribe('/diagnostics')
    assert watch.poll_until(lambda: len(watch.data[diag]) >= 1, 5.0)

    # A client that subscribes to every channel and never reads a byte.
    sleeper = FoxgloveClient(port, timeout=10.0, rcvbuf=4096)
    assert sleeper.wait_channels(watch.channels)
    for topic in list(sleeper.channels):
        sleeper.subscribe(topic)

    # A client that sends garbage.
    bad = websocket.create_connection(f'ws://127.0.0.1:{port}', subprotocols=SUBPROTOCOLS,
                                      timeout=5.0)
    bad.send_binary(b'\x77garbage')                          # unknown binary opcode
    bad.send('this is not JSON')
    bad.send(json.dumps({'op': 'noSuchOp'}))
    bad.send_binary(b'\x01' + struct.pack('<I', 999) + b'\x00' * 12)   # unknown channel id
    bad.send(json.dumps({'op': 'advertise', 'channels': [
        {'id': 1, 'topic': 'torque_command', 'encoding': 'cdr',
         'schemaName': 'std_msgs/msg/Float64'},
        {'id': 2, 'topic': 'axis/joint_states', 'encoding': 'cdr',
         'schemaName': 'sensor_msgs/msg/JointState'}]}))
    time.sleep(0.2)
    bad.send_binary(b'\x01' + struct.pack('<I', 1) + b'\x00\x01\x00\x00' + bytes(200_000))
    bad.send_binary(b'\x01' + struct.pack('<I', 2) + b'\x00\x01\x00\x00' + bytes(8))
    for _ in range(500):                                   # a burst of garbage frames
        bad.send_binary(b'\xff' + bytes(16))

    # Counted (the SDK reports the sleeper's full outbox), and the loop kept 1 kHz.
    t_end = time.monotonic() + 4.0
    assert watch.poll_until(lambda: time.monotonic() > t_end and int(
        diagnostics(watch, diag)[-1]['foxglove_outbox_full_reports']) >= 1, 30.0), (
        diagnostics(watch, diag)[-1])
    js = watch.subscribe('/axis/joint_states')
    assert watch.poll_until(lambda: len(watch.data[js]) >= 200, 5.0), 'the watcher starved'
    last = diagnostics(watch, diag)[-1]
    assert proc.proc.poll() is None, proc.output()
    assert int(last["foxglove_bad_frames"]) >= 503, last
    assert int(last['foxglove_unknown_channels']) >= 1, last
    assert int(last['foxglove_oversized']) == 1, last
    assert int(last['foxglove_refused']) == 1, last
    # The node's rate over the windows with the bad clients: every one at 999-1000 Hz
    # on an idle host; a shared 2-core test host gets a little slack.
    rates = [float(d['achieved_rate_hz']) for d in diagnostics(watch, diag)[-3:]]
    assert min(rates) >= 990.0, rates
    bad.close()
    sleeper.close()
    watch.close()


def _error_lines(text):
    return [ln for ln in text.splitlines() if 'error' in ln.lower()]


@pytest.mark.timeout(60)
def test_port_in_use_one_line_exit_2():
    with socket.socket() as taken:
        taken.bind(('127.0.0.1', 0))
        taken.listen(1)
        port = taken.getsockname()[1]
        out = subprocess.run(
            [sys.executable, '-m', 'leadscrew_sim.node', '--ros-args', '-p', 'record:=false',
             '-p', f'foxglove_port:={port}'], capture_output=True, text=True, timeout=50)
    assert out.returncode == 2, out.stderr
    lines = _error_lines(out.stdout + out.stderr)
    assert len(lines) == 1 and str(port) in lines[0] and 'foxglove_port' in lines[0], lines
    assert 'Traceback' not in out.stderr
    out = subprocess.run(
        [sys.executable, '-m', 'leadscrew_sim.node', '--ros-args', '-p', 'record:=false',
         '-p', 'foxglove_port:=70000'], capture_output=True, text=True, timeout=50)
    assert out.returncode == 2, out.stderr
    lines = _error_lines(out.stdout + out.stderr)
    assert len(lines) == 1 and '70000' in lines[0] and '0-65535' in lines[0], lines
