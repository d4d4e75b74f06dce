"""
``leadscrew_sim commission BAG`` on a real axis's bag: a ros2_control stack's layout, mapped.

The axis is ``simulate --excite commission`` with values chosen here
(tr12x3, its friction moved by the identification tests' factors, a 16-bit
encoder with half a count of noise, a 1 um scale with 0.5 um of noise). Its
states are re-sampled into a rosbag2 bag written by rosbags (an independent
writer) as a robot records them: ``/joint_states`` at the controller's 500 Hz
with jitter and drops, under the robot's joint names, epoch stamps; the
commands as a topic-based hardware interface receives them, one
sensor_msgs/JointState per command on ``/axis/joint_commands`` (a torque as
the screw joint's effort, a nut velocity or position on the nut joint), with
a receipt latency. ``ros2 bag record`` has no segment markers: the parts
come in the sidecar ``excite commission --segments`` writes (times from the
first command). Nothing of the axis is given to ``commission`` but the
mapping, the command delay and the sidecar: not the sensors, not the
friction.

Oracles: the values chosen here (the identify tolerances), the thread's
closed forms for the efficiencies, and the values chosen here re-simulated
on the bag for the held-out error.
"""
import json

import bag_factory as B
from helpers import cli_ok, NS
from leadscrew_sim import load_preset
from mcap_ros2.reader import read_ros2_messages
import numpy as np
import pytest
import yaml

#: The friction truth against the preset's start (the identification tests' factors).
FACTORS = dict(mu_s=1.25, mu_k=0.8, stribeck_velocity=1.3)
#: The axis's own sensors.
SENSORS = dict(encoder_counts=2 ** 16, encoder_noise=0.5 * 2 * np.pi / 2 ** 16,
               scale_resolution=1e-6, scale_noise=5e-7, sensor_seed=11)
#: The identification issue's tolerances: relative.
TOLERANCE = dict(mu_s=0.02, mu_k=0.01, stribeck_velocity=0.10)
COMMANDS = '/axis/joint_commands'
#: The states' interval [ms] (a 500 Hz controller), with this share dropped.
INTERVAL_MS, DROP = 2, 0.02
KIND_TOPICS = {'torque': '/torque_command', 'velocity': '/velocity_command',
               'position': '/position_command'}


def _truth():
    p0 = load_preset('tr12x3')
    values = {n: getattr(p0, n) * f for n, f in FACTORS.items()}
    values.update(SENSORS)
    return values


def _commands(path):
    """Return [(log time [ns], kind, value)] of the simulate run's Float64 commands (mcap_ros2)."""
    out = []
    for m in read_ros2_messages(str(path), topics=list(KIND_TOPICS.values())):
        kind = [k for k, t in KIND_TOPICS.items() if t == m.channel.topic][0]
        out.append((m.log_time_ns, kind, float(m.ros_msg.data)))
    return sorted(out)


def _segments(path):
    """Return {part: (start, end)} [s of log time] of the run's segments record (mcap)."""
    from mcap.reader import make_reader
    with open(path, 'rb') as fh:
        for rec in make_reader(fh).iter_metadata():
            if rec.name == 'leadscrew_sim_segments':
                names = rec.metadata['names'].split(',')
                return {n: tuple(float(x) for x in rec.metadata[n].split()) for n in names}
    raise AssertionError('no segments record')


def write_robot_bag(sim, bag, sidecar):
    """Write the bag and the sidecar of a simulate run; return the first command's time [ns]."""
    stamps, pos, vel, eff = B.sim_states(sim)
    keep = B.irregular(len(stamps), seed=5, lo_ms=INTERVAL_MS, hi_ms=INTERVAL_MS + 1,
                       drop=DROP)
    messages = B.state_messages(stamps, pos, vel, eff, keep)
    commands = _commands(sim)
    for t, kind, value in commands:
        if kind == 'torque':
            msg = B.joint_state(t, (B.SCREW,), [], [], [value])
        elif kind == 'velocity':
            msg = B.joint_state(t, (B.NUT,), [], [value], [])
        else:
            msg = B.joint_state(t, (B.NUT,), [value], [], [])
        messages.append((B.EPOCH + t + B.LATENCY, COMMANDS, 'sensor_msgs/msg/JointState', msg))
    B.write_bag(bag, messages)
    first = commands[0][0]
    doc = {'format': 'leadscrew_sim.segments/1', 'start_ns': B.EPOCH + first + B.LATENCY,
           'segments': {n: [a - first / NS, b - first / NS]
                        for n, (a, b) in _segments(sim).items()}}
    sidecar.write_text(json.dumps(doc))
    return first


def mapping():
    """Return the mapping flags of the robot's bag."""
    return ['--state-topic', B.STATES, '--screw-joint', B.SCREW, '--nut-joint', B.NUT,
            '--command-topic', COMMANDS, '--command-delay', str(-B.LATENCY / NS)]


@pytest.fixture(scope='module')
def commissioned(tmp_path_factory):
    """Return (bag, output dir, report dict, stderr) of the commission of the robot's bag."""
    d = tmp_path_factory.mktemp('commission_bag')
    sim, bag, side, out = d / 'sim.mcap', d / 'robot_bag', d / 'parts.json', d / 'out'
    sets = [a for n, v in _truth().items() for a in ('--set', f'{n}={v!r}')]
    cli_ok('simulate', '--preset', 'tr12x3', '--excite', 'commission', *sets, '-q', '-o', sim)
    write_robot_bag(sim, bag, side)
    r = cli_ok('commission', bag, '-o', out, '--segments', side, *mapping())
    with open(out / 'report.json') as fh:
        report = json.load(fh)
    return bag, out, report, r.stderr


def test_fit_yaml_holds_the_truth(commissioned):
    """fit.yaml of the bag: the identified friction within the identify tolerances."""
    _bag, out, report, err = commissioned
    doc = yaml.safe_load((out / 'fit.yaml').read_text())
    values = doc['/**']['ros__parameters']
    truth = _truth()
    for name, tol in TOLERANCE.items():
        if name == 'stribeck_velocity' and name not in values:
            continue
        assert name in values, (name, values, err[-3000:])
        assert values[name] == pytest.approx(truth[name], rel=tol), (name, values[name])
    assert {'mu_s', 'mu_k'} <= set(values)


def test_the_axis_section_names_the_mapping_and_the_sensors_read(commissioned):
    """The axis section: the mapped topics and joints, and the sensors found in the data."""
    _bag, _out, report, _err = commissioned
    axis = report['sections']['axis']
    assert axis['mapping']['state_topic'] == B.STATES
    assert axis['mapping']['command_topic'] == COMMANDS
    assert axis['mapping']['joints'] == [B.SCREW, B.NUT]
    assert axis['segments_source'].startswith('the sidecar')
    assert set(axis['segments']) == {'sweep', 'breakaway', 'reversals', 'chirp'}
    # the encoder's count read from its readings: 2 pi / 65536 rad per step
    assert axis['sensors']['encoder_counts'] == 2 ** 16


def _truth_twin_errors(bag, window, seeds):
    """Return {seed: RMS [m]} of the truth's twin against the bag's nut on ``window`` [s]."""
    from leadscrew_sim.cli.main import build_parser
    from leadscrew_sim.offline.commission.sources import ForeignAxis
    from leadscrew_sim.offline.options import open_recording
    args = build_parser().parse_args(['identify', str(bag)] + mapping())
    start = load_preset('tr12x3')
    axis = ForeignAxis(open_recording(bag), args, start)
    truth = start.replace(**_truth())
    m = axis.measured
    k = m.window(*window)
    out = {}
    for seed in seeds:
        cols, t = axis.resimulate(truth.replace(sensor_seed=seed), None)
        e = m.nut_position[k] - np.interp(m.time[k], t, cols['nut_position'])
        out[seed] = float(np.sqrt(np.mean(e * e)))
    return out


def test_held_out_error_at_the_closed_loop_noise_floor(commissioned):
    """
    The twin on the reversals (not fitted) is as close as the truth with another noise draw.

    Oracle: the values chosen here re-simulated on the bag's commands. With
    the axis's own noise draw (seed 11) they reproduce the bag to its noise
    (RMS / sigma in [0.8, 1.6]), which checks the comparison. With any other
    draw they do not: the position loop closes over the noisy sensors, and
    where the thread sticks at each target depends on the noise. That error
    (seeds 1 and 2) is the best a twin can do on a recording of unknown noise;
    the calibrated twin must be within 1.5 times it, and the report's floor
    (two calibrated twins of other draws, with the reading's noise) within a
    factor 2 of it.
    """
    bag, _out, report, _err = commissioned
    twin = report['sections']['twin']
    assert 'reversals' in twin['held_out_parts'], twin
    origin = report['time_origin_s']
    assert abs(origin - B.EPOCH / NS) < 1.0        # the report's times count from the bag's start
    window = [origin + t for t in twin['parts']['reversals']['window']]
    errors = _truth_twin_errors(bag, window, (11, 1, 2))
    sigma = twin['noise_um'] * 1e-6
    assert 0.8 <= errors[11] / sigma <= 1.6, (errors, sigma)
    other = 0.5 * (errors[1] + errors[2])
    h = twin['held_out']
    assert h['rms_um'] * 1e-6 <= 1.5 * other, (h, errors)
    assert 0.5 <= h['floor_um'] * 1e-6 / other <= 2.0, (h, errors)
    assert f'to {h["rms_um"]:.3g} um RMS on data it was not fitted to' in twin['sentence']
    assert 'noise floor' in twin['sentence']


def test_friction_from_the_bag_against_the_closed_forms(commissioned):
    """
    The bag's efforts and speeds: efficiencies and breakaway torques against the closed forms.

    As for the axis's own recording (test_commission): the efficiencies at
    the fastest level within 3 %; the breakaway torques at least the static
    closed form and at most 5 % above it.
    """
    from leadscrew_sim.analysis.excitation.profiles import static_breakaway
    from test_commission import efficiency_closed_forms
    _bag, _out, report, _err = commissioned
    f = report['sections']['friction']
    assert len(f['stribeck']) >= 4
    truth = load_preset('tr12x3', **_truth())
    fwd, back = efficiency_closed_forms(truth, f['efficiency_thread']['speed'])
    assert f['efficiency_measured']['forward'] == pytest.approx(fwd, rel=0.03)
    assert f['efficiency_measured']['backdrive'] == pytest.approx(back, rel=0.03)
    up, down = static_breakaway(truth)
    assert up <= f['breakaway']['+'] <= up * 1.05, f['breakaway']
    assert down * 1.05 <= f['breakaway']['-'] <= down, f['breakaway']


def test_chirp_response_measured_from_the_bag(commissioned):
    """The chirp's H1 from the bag: a coherent band, and the drive's Nyquist of the 1 kHz grid."""
    _bag, _out, report, _err = commissioned
    fr = report['sections']['frequency response']
    assert fr.get('measured'), fr['cannot']
    band = fr['measured']['coherent_band_hz']
    assert band is not None and band[1] > band[0]


def test_page_is_written(commissioned):
    """report.html is one page naming the bag and its sections."""
    _bag, out, _report, _err = commissioned
    page = (out / 'report.html').read_text()
    assert 'robot_bag' in page and 'id="twin"' in page
