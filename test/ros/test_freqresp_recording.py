"""
The frequency response of a recording: an ``excite chirp`` run over DDS, recorded by the node.

The node runs as a real process recording to MCAP; ``excite chirp`` runs as
a second process and sends nut velocity commands over DDS. The node's
recording goes through ``recording_response`` (and the ``freqresp`` verb
when it is installed); the oracle is the simulated sine dwell of the full
model (analysis.freqresp.measure, stepped sines with settling periods
discarded) on the same axis, an independent measurement through another
path (no recording, no Welch). The axis is linear (no friction, no
backlash, horizontal), so the chirp and the sines see the same response.
The offline part (no ROS) checks the one-line errors on recordings written
by ``simulate``.
"""
import math
import os
from pathlib import Path
import signal
import subprocess
import sys
import time

from helpers import cli_ok, REPO
from leadscrew_sim import load_preset
from leadscrew_sim.analysis.freqresp.measure import simulated_response
from leadscrew_sim.core.params import ScrewParams
from leadscrew_sim.offline.freqresp.recording import recording_response, RecordingOptions
from leadscrew_sim.offline.options import RunError
import numpy as np
import pytest

#: The linear axis: tr12x3 without friction or backlash, horizontal.
LINEAR = dict(mu_s=0.0, mu_k=0.0, bearing_coulomb=0.0, guide_coulomb=0.0, collar_mu=0.0,
              backlash=0.0, inclination=0.0)
#: The chirp: nut velocity 10 mm/s peak from 3 to 100 Hz in 6 s (the tr12x3 velocity
#: loop's crossover is 50 Hz), 1 kHz commands.
CHIRP = dict(command='velocity', amplitude=0.01, fmin=3.0, fmax=100.0, duration=6.0, settle=0.5)
#: Domain of this module's processes: 201..231, apart from conftest's (1..100) and
#: test_launch's (100..199).
DOMAIN_ID = 201 + os.getpid() % 31
#: Wait between the exciter's exit and the node's stop [s] (as test_excite_node).
DRAIN_S = 1.0


def linear_params():
    """Return the linear axis as ScrewParams."""
    return ScrewParams.from_dict(LINEAR, base=load_preset('tr12x3'))


def opts(options):
    """Return ``--opt name=value`` arguments."""
    return [a for k, v in options.items() for a in ('--opt', f'{k}={v}')]


def compare(resp, oracle):
    """Return (dB, deg, coherence) of resp / oracle at the oracle's frequencies."""
    f = oracle.frequency
    h = np.interp(f, resp.frequency, resp.response.real) + \
        1j * np.interp(f, resp.frequency, resp.response.imag)
    ratio = h / oracle.response
    return (20 * np.log10(np.abs(ratio)), np.degrees(np.angle(ratio)),
            np.interp(f, resp.frequency, resp.coherence))


@pytest.mark.timeout(120)
def test_a_chirp_sent_over_dds_and_recorded_gives_the_sine_dwell_response(
        run_exe, tmp_path, monkeypatch):
    monkeypatch.setenv('ROS_DOMAIN_ID', str(DOMAIN_ID))
    args = ['--ros-args', '-p', f'record_dir:={tmp_path}', '-p', 'record_prefix:=fr',
            '-p', 'preset:=tr12x3', '-p', 'clock_mode:=stepped', '-p', 'real_time_factor:=1.0',
            '-p', 'command_timeout:=2.0']
    for k, v in LINEAR.items():
        args += ['-p', f'{k}:={v}']
    node = run_exe('leadscrew_sim.node', *args)
    r = subprocess.run([sys.executable, '-m', 'leadscrew_sim.cli', 'excite', 'chirp',
                        *opts(CHIRP), '--command-rate', '1000', '--wait-timeout', '60', '-q'],
                       capture_output=True, text=True, timeout=90)
    assert r.returncode == 0 and 'Traceback' not in r.stderr, r.stdout + r.stderr
    time.sleep(DRAIN_S)         # the node takes the last commands at its next ticks
    assert node.stop(signal.SIGINT, timeout=30) == 0, node.output()
    files = sorted(Path(tmp_path).glob('fr_*.mcap'))
    assert len(files) == 1, files

    got = recording_response(files[0], RecordingOptions(
        input='velocity_command', output='motor_velocity', fmin=3.0, fmax=100.0))
    assert got.input == 'velocity_command' and got.source == 'recording'
    # The oracle: a sine dwell of the same amplitude through the full model.
    sine = simulated_response(linear_params(), 'velocity_command', 'motor_velocity',
                              method='sine', fmin=4.0, fmax=90.0, points=10,
                              amplitudes=[CHIRP['amplitude']], workers=1)[0]
    db, deg, coh = compare(got, sine)
    good = coh > 0.95
    # The tolerance: 1 dB and 5 deg wherever the coherence exceeds 0.95,
    # and that must hold over most of the band (the node's own noise-free axis:
    # only the exciter's skipped commands and the chirp's ends lower it).
    assert good.sum() >= 8, (coh, sine.frequency)
    assert np.all(np.abs(db[good]) <= 1.0), (sine.frequency, db, coh)
    assert np.all(np.abs(deg[good]) <= 5.0), (sine.frequency, deg, coh)

    verb = REPO / 'leadscrew_sim' / 'cli' / 'freqresp.py'
    if verb.exists():
        out = tmp_path / 'fr.csv'
        cli_ok('freqresp', files[0], '--input', 'velocity_command', '--output',
               'motor_velocity', '--fmin', 3, '--fmax', 100, '-o', out)
        rows = np.genfromtxt(out, delimiter=',', names=True)
        csv_h = 10 ** (rows['magnitude_db'] / 20) * np.exp(1j * np.radians(rows['phase_deg']))
        from leadscrew_sim.analysis.freqresp import FrequencyResponse
        table = FrequencyResponse(rows['frequency'], csv_h, rows['coherence'], np.nan,
                                  'velocity_command', 'motor_velocity', 'recording')
        db, deg, coh = compare(table, sine)
        good = coh > 0.95
        assert good.sum() >= 8
        assert np.all(np.abs(db[good]) <= 1.0) and np.all(np.abs(deg[good]) <= 5.0)


@pytest.fixture(scope='module')
def runs(tmp_path_factory):
    """Return {name: path} of short recordings written by ``simulate`` (no ROS)."""
    d = tmp_path_factory.mktemp('runs')
    sets = [a for k, v in LINEAR.items() for a in ('--set', f'{k}={v}')]
    chirp = dict(CHIRP, duration=2.0, fmin=5.0)
    cli_ok('simulate', *sets, '--excite', 'chirp',
           *[a for k, v in chirp.items() for a in ('--excite-opt', f'{k}={v}')],
           '-o', d / 'chirp.mcap', '-q')
    cli_ok('simulate', *sets, '--velocity', '0.001', '--duration', '1', '-o',
           d / 'still.mcap', '-q')
    cli_ok('simulate', *sets, '--excite', 'chirp', '--excite-opt', 'command=position',
           '--excite-opt', 'fmin=2', '--excite-opt', 'fmax=40', '--excite-opt', 'duration=3',
           '-o', d / 'position.mcap', '-q')
    return {'chirp': d / 'chirp.mcap', 'still': d / 'still.mcap',
            'position': d / 'position.mcap'}


@pytest.mark.parametrize('run, options, fragment', [
    # the library names the options by their keywords (the command line, by flags)
    ('chirp', dict(input='speed'), "input 'speed' is not an input (torque, velocity_command"),
    ('chirp', dict(output='angle'), "output 'angle' is not an output (motor_angle"),
    ('chirp', dict(input='torque'), 'chirp.mcap: no torque commands on /torque_command'),
    ('chirp', dict(output='following_error'), 'chirp.mcap: the output following_error '
     'needs position commands'),
    ('chirp', dict(screw_joint='z_screw'), 'chirp.mcap: no motor_velocity in the states on '
     '/axis/joint_states (joints z_screw, nut_joint)'),
    ('chirp', dict(state_topic='/ax1/axis/joint_states'),
     'chirp.mcap: no topic /ax1/axis/joint_states'),
    ('chirp', dict(fmin=100.0, fmax=10.0), 'fmax 10 Hz must exceed fmin 100 Hz'),
    ('still', dict(), 'still.mcap: no excitation: velocity_command holds 0.001 throughout'),
    ('nothing', dict(), 'nothing.mcap: no such file'),
])
def test_bad_input_gives_one_error_line(runs, tmp_path, run, options, fragment):
    path = runs.get(run, tmp_path / f'{run}.mcap')
    with pytest.raises(RunError) as info:
        recording_response(path, RecordingOptions(**options))
    msg = str(info.value)
    assert fragment in msg and '\n' not in msg and '--' not in msg, msg


def test_a_simulated_chirp_recording_gives_the_sine_dwell_response(runs):
    # The same comparison on simulate's recording (the model stepped offline,
    # commands on the tick grid): the recording path without DDS.
    got = recording_response(runs['chirp'], RecordingOptions(fmin=5.0, fmax=100.0))
    assert got.input == 'velocity_command'          # the one recorded command
    sine = simulated_response(linear_params(), 'velocity_command', 'motor_velocity',
                              method='sine', fmin=8.0, fmax=90.0, points=6,
                              amplitudes=[CHIRP['amplitude']], workers=1)[0]
    db, deg, coh = compare(got, sine)
    assert np.all(coh > 0.95), coh
    # Noise-free and linear: the estimate's own bias (Hann leakage of the
    # transients over 2 s) stays well inside the 1 dB and 5 deg.
    assert np.all(np.abs(db) <= 0.3) and np.all(np.abs(deg) <= 2.0), (db, deg)


def test_the_following_error_is_the_command_as_a_motor_angle_less_the_motor_angle(runs):
    # following_error = h 2 pi / l x_ref - theta [rad] on the same steps, so its
    # H1 is h 2 pi / l - H1(motor_angle) bin by bin (H1 is linear in the output):
    # the hand sign and the lead of doc/model.md section 3 (tr12x3: right hand,
    # 3 mm), to rounding.
    p = linear_params()
    k = -2 * math.pi / 0.003
    assert p.hand_sign == -1 and p.lead == 0.003
    fe = recording_response(runs['position'], RecordingOptions(output='following_error'))
    th = recording_response(runs['position'], RecordingOptions(output='motor_angle'))
    assert fe.input == 'position_command' and np.array_equal(fe.frequency, th.frequency)
    assert np.max(np.abs(fe.response - (k - th.response))) < 1e-9 * abs(k)


def foreign_copy(src, dst):
    """
    Write simulate's recording as another source would: mapped names, no parameters record.

    Written with mcap_ros2 (not our writer): JointState on /robot/states with
    the joints ``j_motor`` and ``j_carriage``, the velocity commands as
    Float64 on /robot/cmd_vel.
    """
    from leadscrew_sim.io import cdr
    from leadscrew_sim.io.mcap_reader import Recording
    from leadscrew_sim.io.msgdefs import ros2msg_definition
    from mcap_ros2.writer import Writer
    rec = Recording(src, topics=['/axis/joint_states', '/velocity_command'])
    rename = {'screw_joint': 'j_motor', 'nut_joint': 'j_carriage'}
    with open(dst, 'wb') as f:
        w = Writer(f)
        js = w.register_msgdef('sensor_msgs/msg/JointState',
                               ros2msg_definition('sensor_msgs/msg/JointState'))
        fl = w.register_msgdef('std_msgs/msg/Float64', ros2msg_definition('std_msgs/msg/Float64'))
        for t, topic, data in rec.messages:
            if topic == '/axis/joint_states':
                stamp, names, pos, vel, eff = cdr.decode_joint_state(data)
                msg = {'header': {'stamp': {'sec': stamp // 10 ** 9,
                                            'nanosec': stamp % 10 ** 9}, 'frame_id': ''},
                       'name': [rename[n] for n in names], 'position': list(pos),
                       'velocity': list(vel), 'effort': list(eff)}
                w.write_message('/robot/states', js, msg, log_time=t, publish_time=t)
            else:
                w.write_message('/robot/cmd_vel', fl, {'data': cdr.decode_float64(data)},
                                log_time=t, publish_time=t)
        w.finish()


def test_another_sources_recording_maps_its_topics_and_joints_as_identify(runs, tmp_path):
    # The same data under other names, mapped by the options: the same response
    # (the grid from the states' stamps instead of the parameters record).
    path = tmp_path / 'foreign.mcap'
    foreign_copy(runs['chirp'], path)
    mapping = dict(state_topic='/robot/states', command_topic='/robot/cmd_vel',
                   command_kind='velocity', screw_joint='j_motor', nut_joint='j_carriage')
    got = recording_response(path, RecordingOptions(output='nut_velocity', **mapping))
    own = recording_response(runs['chirp'], RecordingOptions(output='nut_velocity'))
    assert got.input == 'velocity_command'
    assert np.array_equal(got.frequency, own.frequency)
    assert np.max(np.abs(got.response - own.response)) <= 1e-12 * np.abs(own.response).max()
    # Without the mapping the states are not found: one line naming the topics.
    with pytest.raises(RunError, match='no topic joint_states for the states'):
        recording_response(path, RecordingOptions())
    with pytest.raises(RunError, match='following_error of a foreign recording needs the axis'):
        recording_response(path, RecordingOptions(output='following_error', **dict(
            mapping, command_kind='position')))
