"""
The stepper axis over DDS from another process (interfaces.md, "Stepper drive (v3)").

The node runs as a real process. Oracles: axis/joint_states is what the
controller believes, the commanded step position, unless the motor has an
encoder (then the encoder's count, within one count of the truth that
sim/joint_states carries); a slipped rotor rests a whole number of electrical
cycles (4 full steps) from the command, the lost full steps diagnostics
reports as simulation truth; torque commands are refused; the recording of a
run with lost steps re-simulates bit for bit.
"""
import math
from pathlib import Path
import signal
import sys

from diagnostic_msgs.msg import DiagnosticArray
from helpers import cli_ok, command_publisher, NodeProcess, Ros, start_node, wait_states
from leadscrew_sim import load_preset
from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory
import pytest
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64

STEP = math.radians(1.8)
LOST_KEY = 'lost_full_steps_simulation_truth'


def diag_values(msg):
    """Return {key: value} of a DiagnosticArray's first status."""
    return {kv.key: kv.value for kv in msg.status[0].values}


def node_argv(directory, *params):
    """Return the argv of a node recording into ``directory`` with prefix ``st``."""
    argv = [sys.executable, '-m', 'leadscrew_sim.node', '--ros-args',
            '-p', f'record_dir:={directory}', '-p', 'record_prefix:=st']
    for p in params:
        argv += ['-p', p]
    return argv


#: A vertical Tr8x8 with an 8 kg bed, stepped beyond its pull-out rate (about 5900 full
#: steps/s, test/core/test_stepper_pullout.py) and stopped again.
OVERSPEED = ('preset:=nema17_tr8x8', 'payload_mass:=8.0', 'max_step_rate:=12000.0',
             'step_acceleration:=8000.0', 'stroke_min:=-5.0', 'stroke_max:=5.0')


@pytest.mark.timeout(300)
def test_lost_steps_reported_recorded_and_resimulated(tmp_path):
    """Lockstep: joint_states is the command, sim/joint_states the slipped rotor; resim bits."""
    proc = NodeProcess(node_argv(tmp_path, 'clock_mode:=lockstep', *OVERSPEED),
                       tmp_path / 'node.log')
    ros = Ros()
    try:
        states = ros.collect(JointState, 'axis/joint_states')
        truth = ros.collect(JointState, 'sim/joint_states')
        diags = ros.collect(DiagnosticArray, 'diagnostics')
        pub = command_publisher(ros, 'axis/joint_commands', JointState, timeout=30.0)
        tpub = command_publisher(ros, 'torque_command')
        p = load_preset('nema17_tr8x8')
        v_fast = 8000.0 * STEP * p.lead_ratio            # [m/s], up: above pull-out
        ticks = [v_fast] * 1000 + [None] + [0.0] * 1500   # None: a torque command
        for k, v in enumerate(ticks):
            if v is None:
                tpub.publish(Float64(data=0.2))           # refused, but it ticks
            else:
                pub.publish(JointState(name=['nut_joint'], velocity=[v]))
            assert ros.spin_until(lambda: len(states) > k, 10.0), (k, proc.output())
        ros.spin_until(lambda: len(diags) >= 2 and diag_values(diags[-1]).get(LOST_KEY, '0')
                       != '0', 5.0)
        ros.spin_for(1.2)                                 # diagnostics after the last tick
        assert proc.stop(signal.SIGINT, timeout=30.0) == 0, proc.output()
    finally:
        proc.stop(signal.SIGKILL)
        ros.close()
    commanded = states[-1].position[0]                     # screw_joint: the commanded angle
    names = list(truth[-1].name)
    rotor = truth[-1].position[names.index('motor_joint')]
    off = (commanded - rotor) / STEP
    assert abs(off - 4.0 * round(off / 4.0)) < 0.5, off
    lost = 4 * round(off / 4.0)
    assert lost != 0
    # axis/joint_states' nut is the commanded angle through the lead (no scale): it went up
    assert states[-1].position[1] > 0.05
    assert truth[-1].position[names.index('nut_joint')] < states[-1].position[1]
    last = diag_values(diags[-1])
    assert last['drive_type'] == 'stepper' and last[LOST_KEY] == str(lost), last
    assert 'simulation truth' in last['lost_full_steps_note']
    assert last['rejected_commands'] == '1'
    # the recording carries the diagnostics with the lost steps
    files = sorted(Path(tmp_path).glob('st_*.mcap'))
    assert len(files) == 1
    with open(files[0], 'rb') as fh:
        reader = make_reader(fh, decoder_factories=[DecoderFactory()])
        recorded = [{kv.key: kv.value for kv in d.status[0].values} for _s, _c, _m, d in
                    reader.iter_decoded_messages(topics=['/diagnostics'])]
    assert recorded and recorded[-1][LOST_KEY] == str(lost)
    r = cli_ok('resim', files[0], '--output', tmp_path / 'st.resim.mcap', '--quiet')
    print(r.stdout)
    assert '(bit-identical)' in r.stdout, r.stdout


@pytest.mark.timeout(180)
def test_encoder_reports_the_rotor_and_torque_is_refused(run_exe, ros):
    """With encoder_counts > 0 axis/joint_states is the encoder, within a count of the truth."""
    counts = 4000
    proc = start_node(run_exe, 'preset:=nema17_tr8x8', f'encoder_counts:={counts}',
                      'command_timeout:=2.0')
    states = ros.collect(JointState, 'axis/joint_states')
    truth = ros.collect(JointState, 'sim/joint_states')
    diags = ros.collect(DiagnosticArray, 'diagnostics')
    wait_states(ros, states, proc)
    pub = command_publisher(ros, 'position_command')
    tpub = command_publisher(ros, 'torque_command')
    x0 = states[-1].position[1]
    target = x0 + 0.004
    for _ in range(300):
        pub.publish(Float64(data=target))
        tpub.publish(Float64(data=0.3))
        ros.spin_for(0.01)
        if abs(states[-1].position[1] - target) < 2e-5 and states[-1].velocity[1] == 0.0:
            break
    ros.spin_for(0.3)
    names = list(truth[-1].name)
    rotor = truth[-1].position[names.index('motor_joint')]
    quantum = 2.0 * math.pi / counts
    assert abs(states[-1].position[0] - rotor) <= quantum, (states[-1].position[0], rotor)
    assert abs(states[-1].position[1] - target) < 2e-5
    # diagnostics come once a second: wait for one published after the refusals
    assert ros.spin_until(lambda: diags and int(diag_values(diags[-1]).get(
        'rejected_commands', 0)) > 0, 5.0), diags and diag_values(diags[-1])
    d = diag_values(diags[-1])
    assert d['joint_states_source'] == 'motor encoder'
    assert d[LOST_KEY] == '0'


@pytest.mark.timeout(120)
def test_effort_interface_refused_at_start(run_exe):
    """A stepper with the fixed effort interface: one error line naming the parameter, exit 2."""
    proc = start_node(run_exe, 'preset:=nema17_tr8x8', 'joint_command_mode:=effort')
    assert proc.wait(60) == 2
    out = proc.output()
    assert "parameter 'joint_command_mode'" in out and 'stepper' in out, out
