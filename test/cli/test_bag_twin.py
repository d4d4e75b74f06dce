"""
The twin against a real axis's bag: ``resim BAG --preset``, ``identify``, ``info``, ``plot``.

The bags are made by rosbags (bag_factory) in ros2_control's layout from
``simulate`` runs with secret values chosen here: joint_state_broadcaster's
states every 2-10 ms with 5 % dropped, epoch stamps; the commands of
forward_command_controller (Float64MultiArray, entry 1 the nut position) or
of joint_trajectory_controller, received 0.4 ms after they were sent
(:data:`bag_factory.LATENCY`: the states lag the commands' log times by
-0.4 ms, the delay to estimate).

Oracles: the sensor noise chosen (the twin's RMS difference at the true
values is the scale's noise level, sqrt(noise^2 + q^2 / 12)); the backlash
difference chosen (a twin with a wrong backlash is off by about it at the
reversals); the secret values (identify's intervals hold them); the latency
chosen (the delay's interval holds -0.4 ms); scipy's cubic Hermite spline
(the trajectory the simulate run followed).
"""
import math
import re

import bag_factory as B
from helpers import cli_ok
import numpy as np
import pytest

#: The vertical tr12x3 with a 16-bit encoder and a noisy scale; secret friction values.
SENSORS = dict(encoder_counts=65536, scale_resolution=1e-7, scale_noise=5e-7)
SECRET = dict(mu_s=0.23, mu_k=0.17)
#: The horizontal axis, ideal encoder, a quantising scale without noise. Where the nut of
#: a horizontal axis comes to rest in its play depends on its start to a fraction of a
#: micrometre (a start 0.2 um off moves the twin 78 um RMS away): a noisy scale's start
#: would make the twin differ by chance; a noise-free one starts it exactly.
FLAT = dict(inclination=0.0, scale_resolution=1e-7)
FLAT_SECRET = dict(backlash=2.3e-4)
#: The scale's noise level [m]: its noise and its quantisation.
SIGMA_X = math.hypot(5e-7, 1e-7 / math.sqrt(12.0))
MAP = ('--command-topic', B.FORWARD, '--command-kind', 'position', '--command-index', '1',
       '--screw-joint', B.SCREW, '--nut-joint', B.NUT)
TRAJ_MAP = ('--command-topic', B.TRAJECTORY, '--command-joint', B.NUT, '--screw-joint',
            B.SCREW, '--nut-joint', B.NUT)
DURATION = 4.0


def _profile(t):
    """Two smooth moves with rests: +10 mm in 1 s from 0.3 s, back to 2 mm from 1.8 s [m]."""
    x = np.zeros_like(t)
    for t0, t1, a, b in ((0.3, 1.3, 0.0, 0.01), (1.8, 2.8, 0.01, 0.002)):
        s = np.clip((t - t0) / (t1 - t0), 0, 1)
        x = np.where(t >= t0, a + (b - a) * (3 * s ** 2 - 2 * s ** 3), x)
    return x


def _sets(values):
    return [a for k, v in values.items() for a in ('--set', f'{k}={v}')]


def _forward_bag(tmp, sets, name, seed=1):
    """Simulate the profile at 100 Hz commands; return (its bag messages, kept state count)."""
    t = np.arange(0.0, DURATION, 0.01)
    x = _profile(t)
    csv = tmp / f'{name}.csv'
    csv.write_text(''.join(f'{a:.6f},{float(b)!r}\n' for a, b in zip(t, x)))
    sim = B.simulate(tmp, sets, csv, DURATION, name=f'{name}.mcap')
    stamps, pos, vel, eff = B.sim_states(sim)
    keep = B.irregular(len(stamps), seed)
    msgs = B.state_messages(stamps, pos, vel, eff, keep)
    for a, b in zip(t, x):
        sent = B.EPOCH + int(round(a * B.NS))
        msgs.append((sent + B.LATENCY, B.FORWARD, 'std_msgs/msg/Float64MultiArray',
                     B.multi_array([0.0, b])))
    return msgs, len(keep)


@pytest.fixture(scope='module')
def bags(tmp_path_factory):
    """Make the bags of the tests: forward commands (one file, split), flat axis, trajectory."""
    tmp = tmp_path_factory.mktemp('bags')
    out = {}
    msgs, n = _forward_bag(tmp, {**SENSORS, **SECRET}, 'forward')
    out['forward'] = B.write_bag(tmp / 'forward', msgs)
    out['n_states'] = n
    mid = sorted(m[0] for m in msgs)[len(msgs) // 2]
    out['split'] = B.split_bag(tmp / 'split', msgs, mid)
    flat, _n = _forward_bag(tmp, {**FLAT, **FLAT_SECRET}, 'flat', seed=2)
    out['flat'] = B.write_bag(tmp / 'flat', flat)
    out['trajectory'] = _trajectory_bag(tmp)
    out['tmp'] = tmp
    return out


def _trajectory_bag(tmp):
    """Make a bag of a joint_trajectory_controller move: four points with velocities."""
    from scipy.interpolate import CubicHermiteSpline
    at = np.array([0.2, 0.9, 1.6, 2.4])            # s after the stamp
    pos = np.array([0.0, 0.006, 0.009, 0.003])
    vel = np.array([0.0, 0.008, -0.002, 0.0])
    spline = CubicHermiteSpline(at, pos, vel)
    t = np.arange(0.0, 3.0, 0.001)                  # the controller's samples at 1 kHz
    x = np.where(t < at[0], pos[0], np.where(t > at[-1], pos[-1],
                                             spline(np.clip(t, at[0], at[-1]))))
    csv = tmp / 'trajectory.csv'
    csv.write_text(''.join(f'{a:.6f},{float(b)!r}\n' for a, b in zip(t, x)))
    sim = B.simulate(tmp, {**SENSORS, **SECRET}, csv, 3.0, name='trajectory.mcap')
    stamps, p, v, e = B.sim_states(sim)
    msgs = B.state_messages(stamps, p, v, e, B.irregular(len(stamps), 3))
    points = [([x0], [v0], int(round(a * B.NS))) for x0, v0, a in zip(pos, vel, at)]
    msgs.append((B.EPOCH + B.LATENCY, B.TRAJECTORY, 'trajectory_msgs/msg/JointTrajectory',
                 B.trajectory(B.EPOCH, (B.NUT,), points)))
    return B.write_bag(tmp / 'trajectory', msgs)


def _table(text):
    """Return {signal: (rms, max, n)} and the delay (value, half width) [s] of a twin report."""
    rows = {}
    for m in re.finditer(r'^(\w+)\s+(\S+)\s+(\S+)\s+(\S+)\s+(\d+)$', text, re.M):
        if m.group(1) != 'signal':
            rows[m.group(1)] = (float(m.group(3)), float(m.group(4)), int(m.group(5)))
    d = re.search(r'delay: (-?[\d.]+) ms \+- ([\d.]+) ms', text)
    delay = (float(d.group(1)) * 1e-3, float(d.group(2)) * 1e-3) if d else None
    return rows, delay


def _twin(bag, *extra):
    r = cli_ok('resim', bag, '--preset', 'tr12x3', *extra)
    return _table(r.stdout) + (r,)


def test_the_twin_with_the_true_values_is_at_the_noise_level(bags):
    """Float64MultiArray commands, irregular states with drops: the scale's noise, the delay."""
    plot = bags['tmp'] / 'twin.png'
    rows, delay, r = _twin(bags['forward'], *MAP, *_sets({**SENSORS, **SECRET}), '--plot', plot)
    rms, _mx, n = rows['nut_position']
    assert n == bags['n_states']
    # the RMS of ~600 Gaussian readings is within 3 % (1/sqrt(2n)) of sigma: 25 % is 8 of those
    assert 0.8 * SIGMA_X <= rms <= 1.25 * SIGMA_X, (rms, SIGMA_X)
    # the delay's interval holds the latency chosen (the states lag the log times by -0.4 ms)
    value, half = delay
    assert abs(value + B.LATENCY / B.NS) <= half, delay
    assert half < 0.1e-3, delay
    # per segment between rests: the two moves, each with its own RMS and max
    segs = re.findall(r'^\s+\d+\s+([\d.]+) \.\.\s+([\d.]+) s', r.stdout, re.M)
    assert len(segs) == 2, r.stdout
    assert float(segs[0][0]) < 0.45 and 1.2 < float(segs[0][1]) < 1.6, segs
    assert plot.stat().st_size > 20_000 and plot.read_bytes()[:8] == b'\x89PNG\r\n\x1a\n'


def test_the_library_comparison_gives_arrays_per_signal_and_segment(bags):
    """twin_comparison (what commissioning calls): RMS/max arrays, per segment, time series."""
    from leadscrew_sim.core.params import ScrewParams
    from leadscrew_sim.core.presets import load_preset
    from leadscrew_sim.offline.foreign.mapping import Mapping
    from leadscrew_sim.offline.foreign.twin import twin_comparison
    from leadscrew_sim.offline.options import open_recording
    rec = open_recording(bags['forward'])
    mapping = Mapping(command_topic=B.FORWARD, command_kind='position', command_index=1,
                      screw_joint=B.SCREW, nut_joint=B.NUT, command_delay=-B.LATENCY / B.NS)
    params = ScrewParams.from_dict({**SENSORS, **SECRET}, base=load_preset('tr12x3'))
    comp = twin_comparison(rec, params, mapping)
    names, rms, mx, seg_rms, seg_max = comp.arrays()
    assert 'nut_position' in names and seg_rms.shape == (2, len(names)) == seg_max.shape
    i = names.index('nut_position')
    assert 0.8 * SIGMA_X <= rms[i] <= 1.25 * SIGMA_X and mx[i] >= rms[i]
    d = comp.measured['nut_position'] - comp.twin['nut_position']
    assert math.isclose(np.sqrt(np.nanmean(d ** 2)), rms[i], rel_tol=1e-12)
    assert comp.delay.how == 'set' and len(comp.time) == bags['n_states']


def test_a_wrong_backlash_shows_as_the_difference(bags):
    """The horizontal axis: the true backlash at the noise level, 0.1 mm off by about that."""
    delay = ('--command-delay', str(-B.LATENCY / B.NS))
    true, _d, _r = _twin(bags['flat'], *MAP, *_sets({**FLAT, **FLAT_SECRET}), *delay)
    q = 1e-7              # the scale's step: a reading lies within one step of the truth
    sigma_q = q / math.sqrt(12.0)
    # each reading within one step of the twin (its interpolation to the stamp: far below)
    assert true['nut_position'][1] <= 1.001 * q and true['screw_angle'][1] < 1e-9, true
    wrong, _d, _r = _twin(bags['flat'], *MAP, *_sets({**FLAT, 'backlash': 1e-4}), *delay)
    diff = FLAT_SECRET['backlash'] - 1e-4
    # at each reversal the nut crosses the play: the twin's is 0.13 mm shorter
    assert wrong['nut_position'][1] >= 0.5 * diff, wrong
    assert wrong['nut_position'][0] >= 100 * sigma_q, wrong


def test_trajectory_commands_sampled_as_the_controller_samples_them(bags):
    """A JointTrajectory with velocities: the twin follows the simulate run to the noise level."""
    rows, delay, _r = _twin(bags['trajectory'], *TRAJ_MAP, *_sets({**SENSORS, **SECRET}))
    assert rows['nut_position'][0] <= 1.25 * SIGMA_X, rows
    assert rows['nut_position'][0] >= 0.8 * SIGMA_X, rows


def test_a_split_bag_gives_the_one_file_bags_numbers(bags):
    """Two files read as one: the same report as the bag in one file (paths aside)."""
    args = (*MAP, *_sets({**SENSORS, **SECRET}))
    one = cli_ok('resim', bags['forward'], '--preset', 'tr12x3', *args).stdout
    two = cli_ok('resim', bags['split'], '--preset', 'tr12x3', *args).stdout
    assert one.replace(str(bags['forward']), 'BAG') == two.replace(str(bags['split']), 'BAG')
    out = bags['tmp'] / 'split.recovered.mcap'
    cli_ok('recover', bags['split'], '-o', out)
    _ran, ok, text = B.mcap_doctor(out)
    assert ok, text


def test_info_prints_the_flags_that_fit(bags):
    """info: topics, types, rates, the joints; its flags line runs resim as given."""
    r = cli_ok('info', bags['forward'])
    assert f'joints {B.SCREW}, {B.NUT}' in r.stdout
    assert 'std_msgs/msg/Float64MultiArray' in r.stdout and 'rate Hz' in r.stdout
    flags = [ln.strip() for ln in r.stdout.splitlines() if ln.strip().startswith('--state-topic')]
    assert len(flags) == 1, r.stdout
    assert '--command-index 1' in flags[0] and '--command-kind position' in flags[0]
    rows, _d, _r = _twin(bags['forward'], *flags[0].split(), *_sets({**SENSORS, **SECRET}))
    assert rows['nut_position'][0] <= 1.25 * SIGMA_X


def test_identify_recovers_the_secret_values_within_its_intervals(bags, tmp_path):
    """mu_s and mu_k from the bag, its sensors given by --set: each interval holds its value."""
    params = tmp_path / 'fitted.yaml'
    r = cli_ok('identify', bags['forward'], '--preset', 'tr12x3', *_sets(SENSORS),
               '--fit', 'mu_s,mu_k', *MAP, '--command-delay', str(-B.LATENCY / B.NS),
               '-o', params)
    for name, truth in SECRET.items():
        m = re.search(rf'^{name}\s+-\s+\S+\s+(\S+)\s+\[(\S+), (\S+)\]\s+(\w+)', r.stdout, re.M)
        assert m, r.stdout
        value, lo, hi = (float(m.group(i)) for i in (1, 2, 3))
        assert m.group(4) == 'identified' and lo <= truth <= hi, (name, m.group(0))
        assert lo <= value <= hi
    # the plot verb re-simulates the twin from the bag with the fitted values
    png = tmp_path / 'twin.png'
    cli_ok('plot', bags['forward'], '--params', params, *MAP, '-o', png)
    assert png.read_bytes()[:4] == b'\x89PNG'


def test_identify_reads_the_sensors_of_irregular_stamps_from_the_data(bags):
    """
    Sensors not given: each level comes from the readings at their own stamps.

    The states come every 2-10 ms with drops, so the plain second difference
    of successive readings holds the speed times the jitter, and the axis
    moves in bursts between samples (its loop follows 100 Hz commands). The
    oracle is the sensors chosen in SENSORS: the noise-free 16-bit encoder
    read as steps of 2 pi / 65536, the scale's hypot(noise, q / sqrt(12)) =
    SIGMA_X. The scale's level is a MAD of the quiet windows, a few hundred
    readings at rest: its relative standard error is near 1.2 / sqrt(200) =
    8.5 %, and 20 % is about two and a half of those. The fit then holds
    the truth.
    """
    r = cli_ok('identify', bags['forward'], '--preset', 'tr12x3', '--fit', 'mu_s,mu_k', *MAP,
               '--command-delay', str(-B.LATENCY / B.NS))
    rows = {m.group(1): (float(m.group(2)), m.group(3)) for m in re.finditer(
        r'^(screw_angle|nut_position)\s+\S+\s+(\S+)\s+\S+\s+\S+\s+\S+\s+(.*)$',
        r.stdout, re.M)}
    assert set(rows) == {'screw_angle', 'nut_position'}, r.stdout
    step = re.search(r'readings in steps of (\S+): q / sqrt\(12\)', rows['screw_angle'][1])
    assert step, rows['screw_angle']
    assert float(step.group(1)) == pytest.approx(2 * math.pi / SENSORS['encoder_counts'],
                                                 rel=1e-3)
    sigma, how = rows['nut_position']
    assert how.startswith('estimated from the data'), how
    assert 0.8 * SIGMA_X <= sigma <= 1.2 * SIGMA_X, (sigma, SIGMA_X)
    for name, truth in SECRET.items():
        m = re.search(rf'^{name}\s+-\s+\S+\s+(\S+)\s+\[(\S+), (\S+)\]\s+(\w+)', r.stdout, re.M)
        assert m and m.group(4) == 'identified', r.stdout
        assert float(m.group(2)) <= truth <= float(m.group(3)), (name, m.group(0))
