"""
The recorder process (``python -m leadscrew_sim.io.recorder``) runs on the io layer alone.

It must start without rclpy, any ROS message package or numba (the node's
start-up and the child's memory stay small), and its parent side
(:class:`leadscrew_sim.io.recorder.Recorder`) must work with a plain logger.
"""
import json
import logging
import subprocess
import sys

from leadscrew_sim.io.cdr import encode_float64
from leadscrew_sim.io.recorder import FRAME, Recorder
from leadscrew_sim.io.session import StorageOptions
from mcap.reader import make_reader

#: Top-level modules the recorder process must never import.
FORBIDDEN = ('rclpy', 'rosidl_runtime_py', 'std_msgs', 'sensor_msgs', 'geometry_msgs',
             'rosgraph_msgs', 'diagnostic_msgs', 'builtin_interfaces', 'numba', 'llvmlite')
#: ... of which the recording session is still allowed numba (see test below).
JIT = ('numba', 'llvmlite')


def run_child(stdin_bytes):
    """Run the recorder module with -X importtime; return (process, imported top-level names)."""
    proc = subprocess.run([sys.executable, '-X', 'importtime', '-m', 'leadscrew_sim.io.recorder'],
                          input=stdin_bytes, capture_output=True, timeout=120)
    imported = set()
    for line in proc.stderr.decode(errors='replace').splitlines():
        # 'import time:      self [us] |  cumulative | imported package'
        if line.startswith('import time:') and '|' in line:
            name = line.rsplit('|', 1)[1].strip()
            if name and name != 'imported package':
                imported.add(name.split('.')[0])
    return proc, imported


def frame(channel, payload, log_time=0):
    """Return the bytes of a pipe frame; channel 0 carries a JSON control record."""
    if channel == 0:
        payload = json.dumps(payload).encode()
    return FRAME.pack(channel, len(payload), log_time) + payload


def test_recorder_module_starts_without_ros_or_numba():
    proc, imported = run_child(b'')
    assert proc.returncode == 0, proc.stderr.decode(errors='replace')[-2000:]
    assert 'leadscrew_sim' in imported
    assert not imported & set(FORBIDDEN), sorted(imported & set(FORBIDDEN))
    status = json.loads(proc.stdout.decode().splitlines()[-1])
    assert status['final'] and status['error'] is None


def test_import_of_recorder_loads_no_ros():
    code = 'import sys, leadscrew_sim.io.recorder; print(" ".join(sorted(sys.modules)))'
    out = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True,
                         timeout=120, check=True).stdout
    top = {m.split('.')[0] for m in out.split()}
    assert not top & set(FORBIDDEN), sorted(top & set(FORBIDDEN))


def test_recording_child_writes_without_ros(tmp_path):
    opening = dict(op='open', options=StorageOptions(str(tmp_path), 'rec').to_dict(),
                   channels=[['/torque_command', 'std_msgs/msg/Float64', None, True]],
                   metadata={'leadscrew_sim_parameters': {'preset': 'tr12x3'}})
    data = frame(0, opening) + b''.join(
        frame(1, encode_float64(0.1 * k), k * 1_000_000) for k in range(5))
    data += frame(0, dict(op='metadata', name='leadscrew_sim_reset',
                          data={'log_time_ns': '3000000'}))
    proc, imported = run_child(data)
    assert proc.returncode == 0, proc.stderr.decode(errors='replace')[-2000:]
    status = json.loads(proc.stdout.decode().splitlines()[-1])
    assert status['final'] and status['error'] is None and status['messages'] == 5
    with open(status['path'], 'rb') as f:
        msgs = list(make_reader(f).iter_messages())
    assert [m.log_time for _s, _c, m in msgs] == [k * 1_000_000 for k in range(5)]
    assert not imported & set(FORBIDDEN), sorted(imported & set(FORBIDDEN))


def test_parent_side_with_a_plain_logger(tmp_path, caplog):
    rec = Recorder(logging.getLogger('test_recorder'))
    channels = {'/torque_command': ('std_msgs/msg/Float64', None, True)}
    assert rec.start(StorageOptions(str(tmp_path), 'parent'), channels, {'preset': 'tr12x3'})
    assert rec.active
    for k in range(10):
        rec.write('/torque_command', encode_float64(float(k)), k * 1_000_000)
    rec.add_metadata('leadscrew_sim_reset', {'log_time_ns': 9_000_000})
    rec.flush()
    with caplog.at_level(logging.INFO, logger='test_recorder'):
        rec.stop()
    assert not rec.active and rec.error is None
    path, size, messages, err = rec.status()
    assert messages == 10 and size > 0 and err is None
    assert 'recording closed' in caplog.text
    with open(path, 'rb') as f:
        reader = make_reader(f)
        assert len(list(reader.iter_messages())) == 10
        meta = {m.name: m.metadata for m in reader.iter_metadata()}
    # One message (k = 9) carries the log time of the reset, 9 ms, and came before it.
    assert meta['leadscrew_sim_reset']['messages_at_log_time'] == '1'
    assert meta['leadscrew_sim_parameters']['preset'] == 'tr12x3'
