"""
The ROS 2 node as a real process, exercised over DDS from the test process.

Every test starts ``python -m leadscrew_sim.node`` (fixture ``run_exe``),
talks to it through real middleware on an isolated domain and stops it.
"""
import math
import os
import signal
import struct
import subprocess
import sys
import time

from diagnostic_msgs.msg import DiagnosticArray
from helpers import (command_publisher, DEEP, MS, NODE, param_msg, publish_until, Ros,
                     stamp_ns, start_node, wait_states)
from leadscrew_sim.core import load_preset
import pytest
from rcl_interfaces.srv import GetParameters, SetParameters, SetParametersAtomically
from rclpy.parameter import Parameter
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64
from std_srvs.srv import Trigger


def latest_diag(diags, key):
    """Value of a key in the latest diagnostics message, or None."""
    if not diags:
        return None
    for kv in diags[-1].status[0].values:
        if kv.key == key:
            return kv.value
    return None


def nut_direction(torque, preset='tr12x3'):
    """Return the expected sign of the nut motion for a torque (doc/model.md section 3)."""
    hand = load_preset(preset).hand
    # Right-hand thread: positive torque (theta sense) moves the nut toward -x.
    return -math.copysign(1.0, torque) if hand == 'right' else math.copysign(1.0, torque)


@pytest.mark.timeout(90)
def test_torque_step_moves_nut_in_documented_direction(run_exe, ros, tmp_path):
    proc = start_node(run_exe, f'record_dir:={tmp_path}', 'record_prefix:=t1', record=True)
    states = ros.collect(JointState, 'axis/joint_states')
    xs = ros.collect(Float64, 'nut_position')
    wait_states(ros, states, proc)
    pub = command_publisher(ros)
    for torque in (0.3, -0.4):
        # From rest: ~/reset restores the initial state (and clears the command).
        assert ros.call(Trigger, f'{NODE}/reset', Trigger.Request()).success
        assert ros.spin_until(lambda: states[-1].effort[0] == 0.0
                              and abs(states[-1].velocity[1]) < 1e-3, 10.0)
        ros.spin_for(0.1)
        start = len(states)
        # The test side may lag behind the 1 kHz stream: wait on the data, not the clock.
        msg = Float64(data=torque)
        assert publish_until(ros, pub, msg,
                             lambda: torque in [s.effort[0] for s in states[start:]])
        publish_until(ros, pub, msg, lambda: False, timeout=0.35)   # 300 steps held
        first = next(i for i in range(start, len(states)) if states[i].effort[0] == torque)
        assert ros.spin_until(lambda: len(states) > first + 300, 10.0)
        dx = states[first + 300].position[1] - states[first - 1].position[1]
        assert abs(dx) > 1e-3, (torque, dx)
        assert math.copysign(1.0, dx) == nut_direction(torque), (torque, dx)

    assert xs, 'no nut_position received'

    # SIGTERM: clean exit, the recording is a complete MCAP file.
    proc.send(signal.SIGTERM)
    assert proc.wait(timeout=30) == 0, proc.output()
    files = sorted(tmp_path.glob('t1_*.mcap'))
    assert files, proc.output()
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory
    with open(files[-1], 'rb') as fh:
        reader = make_reader(fh, decoder_factories=[DecoderFactory()])
        summary = reader.get_summary()
        topics = {c.topic: summary.statistics.channel_message_counts.get(i, 0)
                  for i, c in summary.channels.items()}
        meta = {m.name: m.metadata for m in reader.iter_metadata()}
        ticks = {}                  # log time -> {topic: decoded message}
        for _s, channel, message, decoded in reader.iter_decoded_messages(
                topics=['/axis/joint_states', '/nut_position']):
            ticks.setdefault(message.log_time, {})[channel.topic] = decoded
    # nut_position and the nut_joint position of the same tick agree exactly (the file
    # holds both at the tick's log time; a live subscriber may miss some under load).
    pairs = [(t['/nut_position'].data, t['/axis/joint_states'].position[1]) for t in ticks.values()
             if len(t) == 2]
    assert len(pairs) > 500
    assert all(a == b for a, b in pairs), [p for p in pairs if p[0] != p[1]][:3]
    assert len({b for _a, b in pairs}) > 100      # the nut moved: the check has teeth
    assert topics['/axis/joint_states'] >= len(states)
    assert topics['/torque_command'] > 0
    assert meta['leadscrew_sim_parameters']['preset'] == 'tr12x3'
    assert meta['leadscrew_sim_parameters']['clock_mode'] == 'realtime'
    assert float(meta['leadscrew_sim_parameters']['backlash']) == 1e-4


@pytest.mark.timeout(60)
def test_joint_commands_like_topic_based_ros2_control(run_exe, ros):
    proc = start_node(run_exe)
    states = ros.collect(JointState, 'axis/joint_states')
    diags = ros.collect(DiagnosticArray, 'diagnostics', qos=10)
    wait_states(ros, states, proc)
    pub = command_publisher(ros, 'axis/joint_commands', JointState)
    start = len(states)
    msg = JointState(name=['screw_joint'], effort=[-0.4])
    assert publish_until(ros, pub, msg, lambda: -0.4 in [s.effort[0] for s in states[start:]])
    publish_until(ros, pub, msg, lambda: False, timeout=0.35)       # 300 steps held
    first = next(i for i in range(start, len(states)) if states[i].effort[0] == -0.4)
    assert ros.spin_until(lambda: len(states) > first + 300, 10.0)
    dx = states[first + 300].position[1] - states[first - 1].position[1]
    assert abs(dx) > 1e-3 and math.copysign(1.0, dx) == nut_direction(-0.4)
    # Malformed messages: effort length mismatch is rejected and counted,
    # another joint's name is ignored (never applied).
    pub.publish(JointState(name=['screw_joint'], effort=[]))
    pub.publish(JointState(name=['other_joint'], effort=[0.9]))
    pub.publish(JointState(name=['screw_joint'], effort=[-0.4]))
    ros.spin_until(lambda: latest_diag(diags, 'rejected_commands') not in (None, '0'), 5.0)
    assert latest_diag(diags, 'rejected_commands') == '1'
    assert 0.9 not in [s.effort[0] for s in states]
    # ~/reset restores the initial state and clears the held command.
    res = ros.call(Trigger, f'{NODE}/reset', Trigger.Request())
    assert res.success
    x_init = load_preset('tr12x3').initial_position
    assert ros.spin_until(lambda: abs(states[-1].position[1] - x_init) < 1e-4, 10.0)
    assert states[-1].effort[0] == 0.0


@pytest.mark.timeout(90)
def test_realtime_rate_and_stamps(run_exe, ros, tmp_path):
    # A catch-up budget of 200 steps: on this shared machine the node's thread
    # is now and then descheduled for several ms (up to 8.6 ms seen in 60 s
    # benches); a stall beyond the default budget of 10 steps is a declared
    # skip (an overrun). This test is about the stamping contract, so it gives
    # catch-up room.
    proc = start_node(run_exe, f'record_dir:={tmp_path}', 'max_catchup_steps:=200',
                      record=True)
    raw = []

    def on_raw(data):
        raw.append((time.monotonic(), data))

    ros.node.create_subscription(JointState, 'axis/joint_states', on_raw, DEEP, raw=True)
    wait_states(ros, raw, proc)
    ros.spin_for(1.0)                   # settle
    raw.clear()
    ros.spin_for(10.0)
    assert len(raw) > 1000
    duration = raw[-1][0] - raw[0][0]
    rate = (len(raw) - 1) / duration
    stamps = [struct.unpack_from('<iI', d, 4) for _, d in raw]
    ns = [s * 1_000_000_000 + n for s, n in stamps]
    diffs = {b - a for a, b in zip(ns, ns[1:])}
    print(f'rate {rate:.2f} Hz over {duration:.3f} s, {len(raw)} messages')
    assert diffs == {MS}, sorted(diffs)[:10]
    assert abs(rate - 1000.0) <= 10.0, rate


@pytest.mark.timeout(60)
def test_stepped_mode_publishes_clock(run_exe, ros):
    proc = start_node(run_exe, 'clock_mode:=stepped', 'real_time_factor:=0.5')
    sim = ros.add_node('sim_time_probe', [Parameter('use_sim_time', value=True)])
    states = ros.collect(JointState, 'axis/joint_states')
    wait_states(ros, states, proc)
    assert stamp_ns(states[0]) < 30 * 1_000_000_000      # sim time starts at 0
    samples = []
    end = time.monotonic() + 1.5
    while time.monotonic() < end:
        ros.ex.spin_once(timeout_sec=0.005)
        samples.append(sim.get_clock().now().nanoseconds)
    ros.spin_for(0.3)
    seen = {stamp_ns(s) for s in states}
    samples = [s for s in samples if s > 0]
    assert len(set(samples)) > 50
    missing = [s for s in samples if s not in seen]
    assert not missing, missing[:5]
    ns = [stamp_ns(s) for s in states]
    assert {b - a for a, b in zip(ns, ns[1:])} == {MS}


def lockstep_run(run_exe, commands):
    """Drive a lockstep node with commands one by one; return the states' bits."""
    ros = Ros()
    try:
        proc = start_node(run_exe, 'clock_mode:=lockstep', 'preset:=stick_slip')
        states = ros.collect(JointState, 'axis/joint_states')
        pub = command_publisher(ros, timeout=30.0)
        assert ros.spin_until(lambda: ros.node.count_publishers('/axis/joint_states') > 0, 10.0)
        ros.spin_for(0.5)
        assert not states                      # nothing happens without commands
        for k, torque in enumerate(commands):
            pub.publish(Float64(data=torque))
            assert ros.spin_until(lambda: len(states) > k, 5.0), (k, proc.output())
        ros.spin_for(0.2)
        assert len(states) == len(commands)
        out = []
        for k, s in enumerate(states):
            assert stamp_ns(s) == (k + 1) * MS
            out.append(struct.pack(f'<q{6}d', stamp_ns(s), *s.position, *s.velocity,
                                   *s.effort))
        proc.stop()
        return out
    finally:
        ros.close()


@pytest.mark.timeout(120)
def test_lockstep_is_bit_reproducible(run_exe):
    commands = [0.2 * math.sin(k / 15.0) + (0.15 if (k // 40) % 2 else -0.1)
                for k in range(200)]
    first = lockstep_run(run_exe, commands)
    second = lockstep_run(run_exe, commands)
    assert first == second
    assert len(set(first)) == len(first)


@pytest.mark.timeout(90)
def test_invalid_parameters(run_exe, ros):
    bad = start_node(run_exe, 'backlash:=0.5')
    assert bad.wait(timeout=30) != 0
    out = bad.output()
    assert 'backlash' in out and 'Traceback' not in out, out

    proc = start_node(run_exe)
    states = ros.collect(JointState, 'axis/joint_states')
    wait_states(ros, states, proc)
    res = ros.call(SetParameters, f'{NODE}/set_parameters',
                   SetParameters.Request(parameters=[param_msg('mu_s', -1.0)]))
    assert not res.results[0].successful
    assert 'mu_s' in res.results[0].reason
    # A set the ranges accept but the model refuses: our message names it.
    res = ros.call(SetParameters, f'{NODE}/set_parameters',
                   SetParameters.Request(parameters=[param_msg('backlash', 0.005)]))
    assert not res.results[0].successful
    assert "parameter 'backlash'" in res.results[0].reason and 'pitch' in res.results[0].reason
    # Read-only geometry.
    res = ros.call(SetParameters, f'{NODE}/set_parameters',
                   SetParameters.Request(parameters=[param_msg('pitch', 0.004)]))
    assert not res.results[0].successful
    # All or nothing.
    res = ros.call(SetParametersAtomically, f'{NODE}/set_parameters_atomically',
                   SetParametersAtomically.Request(parameters=[
                       param_msg('mu_k', 0.1), param_msg('backlash', 0.01)]))
    assert not res.result.successful and 'backlash' in res.result.reason

    def get(*names):
        r = ros.call(GetParameters, f'{NODE}/get_parameters',
                     GetParameters.Request(names=list(names)))
        return [v.double_value for v in r.values]

    assert get('mu_k', 'backlash') == [0.15, 1e-4]
    # A valid change goes through.
    res = ros.call(SetParameters, f'{NODE}/set_parameters',
                   SetParameters.Request(parameters=[param_msg('mu_k', 0.1)]))
    assert res.results[0].successful, res.results[0].reason
    assert get('mu_k') == [0.1]
    # Still publishing.
    n = len(states)
    wait_states(ros, states, proc, n + 100, timeout=5.0)
    assert proc.proc.poll() is None


PUBLISHER = """
import sys, time, rclpy
from std_msgs.msg import Float64
rclpy.init()
n = rclpy.create_node('watchdog_commander')
p = n.create_publisher(Float64, 'torque_command', 10)
k = 0
while True:
    k += 1
    p.publish(Float64(data=0.02 + 1e-7 * k))
    time.sleep(0.005)
"""


@pytest.mark.timeout(60)
def test_watchdog_zeroes_torque_after_command_timeout(run_exe, ros, tmp_path):
    timeout_s = 0.5
    proc = start_node(run_exe, f'command_timeout:={timeout_s}')
    states = ros.collect(JointState, 'axis/joint_states')
    wait_states(ros, states, proc)
    log = open(tmp_path / 'commander.log', 'wb')
    cmd = subprocess.Popen([sys.executable, '-c', PUBLISHER], stdout=log,
                           stderr=subprocess.STDOUT, env=dict(os.environ))
    try:
        assert ros.spin_until(lambda: states[-1].effort[0] > 0.0, 20.0)
        ros.spin_for(0.5)
        cmd.send_signal(signal.SIGKILL)
        cmd.wait(timeout=5)
        ros.spin_for(timeout_s + 1.0)
    finally:
        if cmd.poll() is None:
            cmd.kill()
        log.close()
    efforts = [s.effort[0] for s in states]
    last = max(i for i, e in enumerate(efforts) if e != 0.0)
    value = efforts[last]
    first_seen = next(i for i, e in enumerate(efforts) if e == value)
    zero = next(i for i in range(first_seen, len(efforts)) if efforts[i] == 0.0)
    gap = stamp_ns(states[zero]) - stamp_ns(states[first_seen])
    print(f'last command seen at {stamp_ns(states[first_seen])}, zero after {gap / 1e6} ms')
    assert timeout_s * 1e9 <= gap <= timeout_s * 1e9 + MS
    assert all(e == 0.0 for e in efforts[zero:])


@pytest.mark.timeout(60)
def test_non_finite_commands_are_rejected(run_exe, ros):
    proc = start_node(run_exe)
    states = ros.collect(JointState, 'axis/joint_states')
    diags = ros.collect(DiagnosticArray, 'diagnostics', qos=10)
    wait_states(ros, states, proc)
    pub = command_publisher(ros)
    fpub = command_publisher(ros, 'external_force')
    jpub = command_publisher(ros, 'axis/joint_commands', JointState)
    pub.publish(Float64(data=0.01))
    assert ros.spin_until(lambda: states[-1].effort[0] == 0.01, 5.0)
    for _ in range(3):
        pub.publish(Float64(data=float('nan')))
        pub.publish(Float64(data=float('inf')))
        fpub.publish(Float64(data=float('-inf')))
        jpub.publish(JointState(name=['screw_joint'], effort=[float('nan')]))
        pub.publish(Float64(data=0.01))         # keeps the watchdog fed
        ros.spin_for(0.1)
    assert ros.spin_until(lambda: latest_diag(diags, 'rejected_commands') == '12', 5.0), \
        latest_diag(diags, 'rejected_commands')
    assert proc.proc.poll() is None
    for s in states:
        assert all(math.isfinite(v) for v in (*s.position, *s.velocity, *s.effort))
    assert all(s.effort[0] in (0.0, 0.01) for s in states)
    pub.publish(Float64(data=0.01))
    assert ros.spin_until(lambda: states[-1].effort[0] == 0.01, 5.0)
