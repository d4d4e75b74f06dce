"""
Bad input in a foreign bag: one line that names the option and the value, and nothing lost.

Small bags written by rosbags: a topic that is not there (the known ones
listed), a joint missing from the states, an index past the array, stamps
that run backwards, an unknown command type, no overlap between commands and
states, and NaN commands (counted and skipped as the node does: the run then
equals the run of the bag without them).
"""
import hashlib

import bag_factory as B
from helpers import cli
import numpy as np
import pytest

MAP = ['--preset', 'tr12x3', '--command-topic', B.FORWARD, '--command-kind', 'position',
       '--command-index', '1', '--screw-joint', B.SCREW, '--nut-joint', B.NUT,
       '--command-delay', '0']


def _bag(path, states=None, commands=None, extra=()):
    """Write states at 250 Hz for 2 s and position commands at 100 Hz (a 1 mm ramp)."""
    msgs = list(extra)
    regular = B.EPOCH + np.arange(1, 500) * 4_000_000
    stamps = states if states is not None else regular
    logs = regular if len(stamps) == len(regular) and stamps[0] == regular[0] else stamps
    for log, s in zip(logs, stamps):
        msgs.append((int(log) + 100_000, B.STATES, 'sensor_msgs/msg/JointState',
                     B.joint_state(int(s), (B.SCREW, B.NUT), [0.0, 0.0], [0.0, 0.0],
                                   [0.0, 0.0])))
    for i, value in enumerate(commands if commands is not None else
                              np.linspace(0.0, 1e-3, 200)):
        msgs.append((B.EPOCH + i * 10_000_000, B.FORWARD, 'std_msgs/msg/Float64MultiArray',
                     B.multi_array([0.0, value])))
    return B.write_bag(path, msgs)


def _digest(bag):
    return {p.name: hashlib.sha256(p.read_bytes()).hexdigest() for p in sorted(bag.iterdir())}


def _one_line(r, *words):
    lines = [ln for ln in r.stderr.splitlines() if ln.strip()]
    assert r.returncode == 1 and len(lines) == 1, r.stdout + r.stderr
    assert lines[0].startswith('leadscrew_sim: error:'), lines
    for w in words:
        assert w in lines[0], (w, lines[0])
    return lines[0]


@pytest.fixture(scope='module')
def good(tmp_path_factory):
    return _bag(tmp_path_factory.mktemp('good') / 'bag')


@pytest.mark.parametrize('verb', ['resim', 'identify', 'plot', 'commission'])
def test_a_topic_not_there_lists_the_known_ones(good, verb, tmp_path):
    before = _digest(good)
    args = [a if a != B.FORWARD else '/nope/commands' for a in MAP]
    out = ['-o', str(tmp_path / 'report')] if verb == 'commission' else []
    _one_line(cli(verb, good, *args, *out), '--command-topic /nope/commands', 'no such topic',
              B.FORWARD, B.STATES)
    assert _digest(good) == before
    assert not (tmp_path / 'report').exists()


def test_a_joint_missing_from_the_states(good):
    args = [a if a != B.NUT else 'carriage_joint' for a in MAP]
    _one_line(cli('resim', good, *args), '--nut-joint carriage_joint', B.SCREW, B.NUT)


def test_an_index_past_the_array(good):
    args = [a if a != '1' else '2' for a in MAP]
    _one_line(cli('resim', good, *args), '--command-index 2', 'past the array', '2 entries')


def test_stamps_that_run_backwards(tmp_path):
    stamps = B.EPOCH + np.arange(1, 500) * 4_000_000
    stamps[300] = stamps[200]
    bag = _bag(tmp_path / 'bag', states=stamps)
    _one_line(cli('resim', bag, *MAP), 'run backwards', 'message 300', B.STATES)


def test_no_overlap_between_commands_and_states(tmp_path):
    stamps = B.EPOCH + 60 * B.NS + np.arange(1, 500) * 4_000_000
    bag = _bag(tmp_path / 'bag', states=stamps)
    _one_line(cli('resim', bag, *MAP), 'no overlap', B.FORWARD, B.STATES)


def test_an_unknown_command_type_is_refused_by_name(tmp_path):
    T = B.TYPESTORE.types
    extra = [(B.EPOCH + i, '/gripper/name', 'std_msgs/msg/String', T['std_msgs/msg/String'](
        data='x')) for i in range(3)]
    bag = _bag(tmp_path / 'bag', extra=extra)
    args = [a if a != B.FORWARD else '/gripper/name' for a in MAP]
    _one_line(cli('resim', bag, *args), "'std_msgs/msg/String' is not read",
              'std_msgs/msg/Float64MultiArray', 'trajectory_msgs/msg/JointTrajectory')


def test_nan_commands_are_counted_and_skipped(tmp_path):
    """Three NaN commands: said, and the twin equals the one of the bag without them."""
    values = np.linspace(0.0, 1e-3, 200)
    with_nan = values.copy()
    with_nan[[50, 51, 120]] = np.nan
    bag = _bag(tmp_path / 'nan', commands=with_nan)
    r = cli('resim', bag, *MAP)
    assert r.returncode == 0, r.stderr
    assert '197 taken, 3 non-finite skipped' in r.stdout, r.stdout
    # the same commands without the three messages: held values are the same, so the same run
    msgs = []
    stamps = B.EPOCH + np.arange(1, 500) * 4_000_000
    for s in stamps:
        msgs.append((int(s) + 100_000, B.STATES, 'sensor_msgs/msg/JointState',
                     B.joint_state(int(s), (B.SCREW, B.NUT), [0.0, 0.0], [0.0, 0.0],
                                   [0.0, 0.0])))
    for i, v in enumerate(with_nan):
        if np.isfinite(v):
            msgs.append((B.EPOCH + i * 10_000_000, B.FORWARD,
                         'std_msgs/msg/Float64MultiArray', B.multi_array([0.0, v])))
    clean = B.write_bag(tmp_path / 'clean', msgs)
    r2 = cli('resim', clean, *MAP)
    assert r2.returncode == 0, r2.stderr

    def table(text):
        return [ln for ln in text.splitlines() if ln.split() and ln.split()[0] in (
            'screw_angle', 'motor_torque', 'nut_position')]
    assert table(r.stdout) == table(r2.stdout) and len(table(r.stdout)) == 3


def test_a_foreign_bag_without_the_twins_parameters(good):
    _one_line(cli('resim', good, '--command-topic', B.FORWARD), 'give the twin',
              '--preset', 'leadscrew_sim info')


def test_a_bad_map_file(good, tmp_path):
    m = tmp_path / 'map.yaml'
    m.write_text('command_topic: /forward_position_controller/commands\ncommand_indx: 1\n')
    _one_line(cli('resim', good, '--preset', 'tr12x3', '--map', m), "'command_indx'",
              'command_index')
    m.write_text('command_topic: /forward_position_controller/commands\ncommand_index: 1\n'
                 'command_kind: position\nscrew_joint: axis_screw_joint\n'
                 'nut_joint: axis_nut_joint\ncommand_delay: 0\n')
    r = cli('resim', good, '--preset', 'tr12x3', '--map', m)
    assert r.returncode == 0 and 'command-to-state delay: 0.000 ms (set' in r.stdout, r.stderr


def test_commission_of_a_bag_without_its_mapping_names_the_way(good, tmp_path):
    """No parameter record and no mapping flags: one line naming them and info, no file."""
    before = _digest(good)
    out = tmp_path / 'report'
    r = cli('commission', good, '-o', out)
    line = _one_line(r, 'does not map to an axis', '--command-topic', 'leadscrew_sim info')
    assert str(good) in line
    assert not out.exists()
    assert _digest(good) == before


@pytest.mark.parametrize('verb', ['resim', 'identify'])
def test_a_command_topic_that_does_not_move_the_axis(verb, tmp_path):
    """
    Velocity commands all 0 while the nut moves 1 mm: one line names the topic and the travel.

    The oracle is the bag's own content: a twin driven by zero velocity holds
    the axis, so no fit could explain a nut that travels 1 mm.
    """
    msgs = []
    stamps = B.EPOCH + np.arange(1, 500) * 4_000_000
    for i, s in enumerate(stamps):
        x = 1e-3 * i / len(stamps)
        msgs.append((int(s) + 100_000, B.STATES, 'sensor_msgs/msg/JointState',
                     B.joint_state(int(s), (B.SCREW, B.NUT), [x / 4.7746e-4, x], [0.0, 0.0],
                                   [0.0, 0.0])))
    for i in range(200):
        msgs.append((B.EPOCH + i * 10_000_000, B.FORWARD, 'std_msgs/msg/Float64MultiArray',
                     B.multi_array([0.0, 0.0])))
    bag = B.write_bag(tmp_path / 'bag', msgs)
    before = _digest(bag)
    args = [a if a != 'position' else 'velocity' for a in MAP]
    r = cli(verb, bag, *args)
    _one_line(r, B.FORWARD, 'does not move the axis', '200 velocity commands, all 0',
              'nut_position over 0.000998 m')
    assert _digest(bag) == before
