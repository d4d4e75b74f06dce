"""
The node's ageing over DDS: a state file that carries one axis's wear across runs.

A node wears its axis (velocity commands, a time-lapse ageing_speedup), is
stopped with SIGINT and started again on the same ageing_state_file; the
second run starts where the first stopped. The oracle is the first run's own
end: its file (read back by the file reader) and its recording's end record
(read by the mcap library), against the second run's first live sim/ageing
message and its recording's start record. A file the node cannot use is
left untouched while the node runs from a new axis.
"""
import signal

import pytest
from diagnostic_msgs.msg import DiagnosticArray
from std_msgs.msg import Float64, Float64MultiArray
from std_srvs.srv import Trigger

from helpers import command_publisher, NodeProcess, publish_until, wait_states
from leadscrew_sim.core.presets import load_preset
from leadscrew_sim.io.ageing_file import read_state
from leadscrew_sim.io.messages import AGEING_VALUES
from leadscrew_sim.io.run_file import AGEING_END_RECORD, AGEING_KEY, PARAMS_RECORD
from mcap.reader import make_reader
from sensor_msgs.msg import JointState

AGEING = ['wear_rate:=1e-9', 'ageing_speedup:=1e4', 'lubricant_life:=1.0',
          'screw_heat_capacity:=50.0']


def _argv(tmp_path, name, state_file, *extra):
    import sys
    args = [sys.executable, '-m', 'leadscrew_sim.node', '--ros-args',
            '-p', 'clock_mode:=stepped', '-p', 'real_time_factor:=1.0',
            '-p', f'record_dir:={tmp_path}', '-p', f'record_prefix:={name}',
            '-p', f'ageing_state_file:={state_file}']
    for p in AGEING + list(extra):
        args += ['-p', p]
    return args


def _metadata(path, name):
    with open(path, 'rb') as fh:
        for m in make_reader(fh).iter_metadata():
            if m.name == name:
                return dict(m.metadata)
    return None


def _recording(tmp_path, name):
    files = sorted(tmp_path.glob(f'{name}*.mcap'))
    assert len(files) == 1, files
    return files[0]


@pytest.mark.timeout(240)
def test_a_restarted_node_continues_from_the_saved_ageing(tmp_path, ros):
    state_file = tmp_path / 'axis.json'
    live = ros.collect(Float64MultiArray, 'sim/ageing')
    states = ros.collect(JointState, 'axis/joint_states')
    diags = ros.collect(DiagnosticArray, 'diagnostics')
    first = NodeProcess(_argv(tmp_path, 'first', state_file), tmp_path / 'first.log')
    try:
        wait_states(ros, states, first)
        pub = command_publisher(ros, 'velocity_command')
        worn = publish_until(ros, pub, Float64(data=0.01),
                             lambda: live and live[-1].data[0] > 2e-6, timeout=60)
        assert worn, first.output()
        assert live[-1].layout.dim[0].label == ','.join(AGEING_VALUES)

        def worn_diag():
            # the values are printed to 6 digits: the first diagnostics with wear can still
            # read a lubricant of '1' (it falls as exp(-sliding distance / lubricant_life))
            for d in diags[::-1]:
                kv = {v.key: v.value for v in d.status[0].values}
                if float(kv.get('wear_leading_m', 0.0)) > 0.0 and \
                        float(kv.get('lubricant', 1.0)) < 1.0:
                    return kv
            return None

        assert ros.spin_until(lambda: worn_diag() is not None, 10), 'no ageing in diagnostics'
        kv = worn_diag()
        assert 0.0 < float(kv['lubricant']) < 1.0 and float(kv['backlash_m']) > 1e-4
        first.send(signal.SIGINT)
        assert first.wait(timeout=30) == 0, first.output()
        assert 'does not exist yet' in first.output()
    finally:
        first.stop(signal.SIGKILL)
    saved = read_state(state_file, load_preset('tr12x3'), 'tr12x3')
    assert saved['wear_leading_a'] > 2e-6 and saved['lubricant'] < 1.0
    end = _metadata(_recording(tmp_path, 'first'), AGEING_END_RECORD)
    assert {k: float(end[AGEING_KEY + k]) for k in saved} == saved

    ros.spin_for(0.5)          # take what the first node still had in flight, then drop it
    del live[:]
    second = NodeProcess(_argv(tmp_path, 'second', state_file), tmp_path / 'second.log')
    try:
        assert ros.spin_until(lambda: live or second.proc.poll() is not None, 60), \
            second.output()
        got = dict(zip(AGEING_VALUES, live[0].data))
        # the nut stands (it settles on its worn flank by nanometres at start): wear and
        # lubricant are the saved ones
        assert got['wear_leading'] == pytest.approx(
            saved['wear_leading_a'] + saved['wear_leading_b'], rel=1e-6)
        assert got['lubricant'] == pytest.approx(saved['lubricant'], rel=1e-6)
        resp = ros.call(Trigger, 'leadscrew_sim_node/relubricate', Trigger.Request())
        assert resp.success
        assert ros.spin_until(lambda: dict(zip(AGEING_VALUES, live[-1].data))['lubricant']
                              > 1.0 - 1e-9, 10)
        second.send(signal.SIGINT)
        assert second.wait(timeout=30) == 0, second.output()
        assert 'ageing state loaded from' in second.output()
    finally:
        second.stop(signal.SIGKILL)
    start = _metadata(_recording(tmp_path, 'second'), PARAMS_RECORD)
    assert {k: float(start[AGEING_KEY + k]) for k in saved} == saved
    assert read_state(state_file, load_preset('tr12x3'), 'tr12x3')['lubricant'] > 1.0 - 1e-9


@pytest.mark.timeout(120)
def test_a_state_file_of_another_axis_is_reported_and_left_as_it_is(tmp_path, ros):
    other = tmp_path / 'other.json'
    first = NodeProcess(_argv(tmp_path, 'tr8', other, 'preset:=tr8x8'), tmp_path / 'tr8.log')
    states = ros.collect(JointState, 'axis/joint_states')
    try:
        wait_states(ros, states, first)
        first.send(signal.SIGINT)
        assert first.wait(timeout=30) == 0, first.output()
    finally:
        first.stop(signal.SIGKILL)
    before = other.read_bytes()
    del states[:]
    proc = NodeProcess(_argv(tmp_path, 'tr12', other), tmp_path / 'tr12.log')
    try:
        wait_states(ros, states, proc, n=50)    # it runs, from a new axis
        proc.send(signal.SIGINT)
        assert proc.wait(timeout=30) == 0, proc.output()
        text = proc.output()
    finally:
        proc.stop(signal.SIGKILL)
    lines = [ln for ln in text.splitlines() if 'other.json' in ln]
    assert len(lines) == 1 and "written for preset 'tr8x8'" in lines[0], text
    assert other.read_bytes() == before
