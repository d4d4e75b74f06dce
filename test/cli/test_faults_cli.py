"""
``leadscrew_sim simulate --faults FILE``: scheduled sensor, communication and mechanical faults.

Every run is a real ``python -m leadscrew_sim.cli`` subprocess; its MCAP file
is read with the mcap reader (+ mcap_ros2 decoder) or with rosbags'
AnyReader, never with our own reader. Expected values come from the
schedule itself (the first step at or after each time, in exact decimal
arithmetic), from the truth topic ``sim/joint_states`` of the same file,
from the sensor definitions (floor quantisation, Gaussian noise) or from a
binomial bound.
"""
from fractions import Fraction
import hashlib
import math
from pathlib import Path
import re

from helpers import cli, cli_ok, MS, NS
import pytest

UPDATE_RECORD = 'leadscrew_sim_parameters_update'
PARAMS_RECORD = 'leadscrew_sim_parameters'
DT_NS = MS                       # every run here is at the default 1 kHz

#: Quantised and noisy sensors: 4096 counts/rev (1.53 mrad) with 2 mrad noise, a 1 um
#: scale with 0.5 um noise.
COUNTS, ENC_NOISE, RES, SCALE_NOISE = 4096, 2e-3, 1e-6, 5e-7
SENSORS = ['--set', f'encoder_counts={COUNTS}', '--set', f'encoder_noise={ENC_NOISE}',
           '--set', f'scale_resolution={RES}', '--set', f'scale_noise={SCALE_NOISE}',
           '--set', 'sensor_seed=7']
#: Quantised sensors without noise (a reading is the floor of the truth).
QUANTISED = ['--set', f'encoder_counts={COUNTS}', '--set', f'scale_resolution={RES}']
#: The drive samples the sensors every m = max(1, round(nsub / (dt drive_rate))) substeps
#: on a grid that runs on across steps. tr12x3 has nsub = 18: 6000 Hz gives m = 3, which
#: divides 18, so every step ends on a drive sample; at the default 4000 Hz (m = 5) a step
#: reports a reading taken at its end between two drive samples. Tests that compare
#: readings with the truth at their stamp run both ways.
STEP_END = ['--set', 'drive_rate=6000']
COUNT = 2.0 * math.pi / COUNTS   # one encoder count [rad]

#: A schedule of every kind of change; several times are not whole steps (0.1995 s acts
#: from the step at 0.2 s, 0.2505 s from 0.251 s, 0.3001 s from 0.301 s), two share 0.5 s.
FULL_SCHEDULE = """time,parameter,value
# encoder frozen from the step at 0.2 s to the step at 0.4 s
0.1995,fault.encoder_freeze,true
0.2505,fault.state_drop_rate,0.3
0.3,state_delay,3
0.3001,command_delay,2
0.35,fault.command_drop_rate,0.2
0.4,fault.encoder_freeze,false
0.45,fault.motor_torque_scale,0.5
0.5,fault.jam_position,0.0005
0.5,fault.jam,true
0.6,fault.state_drop_rate,0
0.7,state_delay,0
"""
FULL_DURATION = 0.8

#: The inputs of simulate: two torque inputs, two drive inputs (velocity loop, position loop).
INPUTS = {
    'sine': ['--profile', 'sine', '--amplitude', 0.1, '--frequency', 2.0],
    'torque_csv': ['--torque-csv', '{dir}/torque.csv'],
    'velocity_csv': ['--velocity-csv', '{dir}/velocity.csv'],
    'trapezoid': ['--profile', 'trapezoid', '--target', 0.003, '--speed', 0.01,
                  '--accel', 0.1],
}


# ---------------------------------------------------------------------------
# helpers: running simulate, reading its file with independent readers
# ---------------------------------------------------------------------------

def _inputs(name, tmp):
    """Return the simulate options of input ``name``, writing its CSV into ``tmp``."""
    (tmp / 'torque.csv').write_text('time,torque\n0,0.08\n0.25,-0.05\n0.55,0.1\n')
    (tmp / 'velocity.csv').write_text('time,velocity\n0,0.002\n0.3,-0.001\n0.6,0.003\n')
    return [str(a).format(dir=tmp) for a in INPUTS[name]]


def _simulate(tmp, name, schedule, duration, *args, step_end=False):
    """
    Run simulate with schedule text ``schedule``; return the output path.

    ``step_end``: assert that the drive period (the sensors' sampling period,
    m = max(1, round(nsub / (dt drive_rate))) substeps) divides the step, so
    that the last sample of each step is taken at its end, the stamp of its
    axis/joint_states.
    """
    faults = tmp / f'{name}.faults.csv'
    faults.write_text(schedule)
    out = tmp / f'{name}.mcap'
    r = cli_ok('simulate', '--duration', duration, '--faults', faults, *args, '--output', out,
               '--quiet')
    if step_end:
        nsub = int(re.search(r'(\d+) substeps/step', r.stdout).group(1))
        rate = float(re.search(r'drive_rate=(\S+)', ' '.join(map(str, args))).group(1))
        m = max(1, math.floor(nsub / (DT_NS / NS * rate) + 0.5))
        assert nsub % m == 0, (nsub, m)
    return out


def _stamp(msg):
    return msg.header.stamp.sec * NS + msg.header.stamp.nanosec


def _read_mcap(path):
    """Return ({record name: [metadata dicts]}, {topic: [(log time, decoded message)]})."""
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory
    meta, topics = {}, {}
    with open(path, 'rb') as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        for m in reader.iter_metadata():
            meta.setdefault(m.name, []).append(dict(m.metadata))
        for _s, channel, message, decoded in reader.iter_decoded_messages(
                log_time_order=False):
            topics.setdefault(channel.topic, []).append((message.log_time, decoded))
    return meta, topics


def _read_rosbags(path, topics=('/axis/joint_states', '/sim/joint_states', '/nut_position')):
    """Return {topic: [(log time, deserialized message)]} read with rosbags' AnyReader."""
    from rosbags.highlevel import AnyReader
    out = {t: [] for t in topics}
    with AnyReader([Path(path)]) as r:
        conns = [c for c in r.connections if c.topic in topics]
        for conn, log_time, raw in r.messages(connections=conns):
            out[conn.topic].append((log_time, r.deserialize(raw, conn.msgtype)))
    return out


def _truth(sim_js):
    """Return {stamp: (motor, screw, nut) positions, velocities, efforts} of sim/joint_states."""
    out = {}
    for _t, m in sim_js:
        assert list(m.name)[:3] == ['motor_joint', 'screw_joint', 'nut_joint']
        out[_stamp(m)] = (list(m.position), list(m.velocity), list(m.effort))
    return out


def _first_step(text):
    """Return the first step index at or after time ``text`` [s] (exact decimal arithmetic)."""
    return math.ceil(Fraction(text) * NS / DT_NS)


def _value(text):
    """Return a schedule or record value as bool or float ('true'/'True', numbers)."""
    if text.strip().lower() in ('true', 'false'):
        return text.strip().lower() == 'true'
    return float(text)


def _schedule_rows(schedule):
    """Return the (time text, parameter, value text) rows of a schedule."""
    rows = []
    for line in schedule.splitlines()[1:]:
        line = line.split('#', 1)[0].strip()
        if line:
            rows.append(tuple(c.strip() for c in line.split(',')))
    return rows


def _overall(stdout):
    m = re.search(r'overall max \|diff\|: (\S+)', stdout)
    assert m, stdout
    return float(m.group(1))


# ---------------------------------------------------------------------------
# 1. the schedule is recorded as parameter updates and resim replays it
# ---------------------------------------------------------------------------

@pytest.mark.parametrize('source', list(INPUTS))
def test_schedule_recorded_as_updates(source, tmp_path):
    """One update record per scheduled time, at the first step at or after it, ROS names."""
    out = _simulate(tmp_path, source, FULL_SCHEDULE, FULL_DURATION, *_inputs(source, tmp_path),
                    *SENSORS)
    meta, topics = _read_mcap(out)
    expected = {}                   # step -> {ROS name: value}
    for t, name, value in _schedule_rows(FULL_SCHEDULE):
        expected.setdefault(_first_step(t), {})[name] = _value(value)
    assert sorted(expected) == [200, 251, 300, 301, 350, 400, 450, 500, 600, 700]
    updates = meta[UPDATE_RECORD]
    assert len(updates) == len(expected)
    got = {}
    for rec in updates:
        log_time = int(rec.pop('log_time_ns'))
        assert log_time % DT_NS == 0, log_time
        assert log_time // DT_NS not in got, f'two records at {log_time} ns'
        assert rec.pop('messages_at_log_time') == '0'   # before the messages of that time
        got[log_time // DT_NS] = {k: _value(v) for k, v in rec.items()}
    assert got == expected
    # The --set sensors are the run's parameters.
    params = meta[PARAMS_RECORD][0]
    assert int(params['encoder_counts']) == COUNTS and float(params['encoder_noise']) == ENC_NOISE
    assert float(params['scale_resolution']) == RES and params['sensor_seed'] == '7'
    assert params['fault.encoder_freeze'] == 'False' and params['state_delay'] == '0'
    # The truth topic has every tick, whatever the faults.
    stamps = [_stamp(m) for _t, m in topics['/sim/joint_states']]
    assert stamps == [k * DT_NS for k in range(1, 801)]


#: The full schedule without its command losses (torque mode then replays exactly).
NO_COMMAND_LOSS = '\n'.join(line for line in FULL_SCHEDULE.splitlines()
                            if 'command_drop_rate' not in line) + '\n'


@pytest.mark.parametrize('source,schedule', [
    pytest.param('sine', FULL_SCHEDULE, id='sine'),
    pytest.param('torque_csv', FULL_SCHEDULE, id='torque_csv'),
    pytest.param('velocity_csv', FULL_SCHEDULE, id='velocity_csv'),
    pytest.param('trapezoid', FULL_SCHEDULE, id='trapezoid'),
    pytest.param('sine', NO_COMMAND_LOSS, id='sine_without_command_loss'),
    pytest.param('torque_csv', NO_COMMAND_LOSS, id='torque_csv_without_command_loss'),
])
def test_schedule_resim_bit_identical(source, schedule, tmp_path):
    """Resim of a scheduled-fault file reproduces every recorded state bit for bit."""
    out = _simulate(tmp_path, source, schedule, FULL_DURATION, *_inputs(source, tmp_path),
                    *SENSORS)
    r = cli_ok('resim', out, '--output', tmp_path / 'again.mcap')
    assert 'compared 800 recorded ticks' in r.stdout, r.stdout
    # Same doubles through the same code path: exact equality, no tolerance.
    assert _overall(r.stdout) == 0.0, r.stdout
    assert '(bit-identical)' in r.stdout, r.stdout


def test_command_drop_counts_commands_since_start(tmp_path):
    """With fault.command_drop_rate from 0.35 s, command n is lost iff uniform(seed, 3, n) < p."""
    from leadscrew_sim.core.engine.sensors import STREAM_COMMAND_DROP, uniform
    p, seed, k_on = 0.2, 7, 350
    # the sine runs the axis past the preset's overspeed trip: off here (max_screw_velocity 0)
    out = _simulate(tmp_path, 'drop', f'time,parameter,value\n0.35,fault.command_drop_rate,{p}\n',
                    FULL_DURATION, '--profile', 'sine', '--amplitude', 0.1, '--frequency', 2.0,
                    '--set', f'sensor_seed={seed}', '--set', 'max_screw_velocity=0.0')
    _meta, topics = _read_mcap(out)
    sent = {t // DT_NS: m.data for t, m in topics['/torque_command']}
    motor = {_stamp(m) // DT_NS: m.effort[0] for _t, m in topics['/sim/joint_states']}
    # Without a motor lag the motor torque of step k (stamp k + 1) is the command the drive
    # applies: the one sent at k, or, when that was lost, the one held from before. The sine
    # sends a new value every step, so a lost command shows as motor torque != sent torque.
    lost = {k for k in range(800) if motor[k + 1] != sent[k]}
    assert all(motor[k + 1] == motor[k] for k in lost)        # held, not zeroed
    # The commands are counted from the first one (n = k: one torque_command per step).
    oracle = {k for k in range(k_on, 800) if uniform(seed, STREAM_COMMAND_DROP, k) < p}
    assert lost == oracle, (sorted(lost)[:10], sorted(oracle)[:10])


# ---------------------------------------------------------------------------
# 2. the effects in the file
# ---------------------------------------------------------------------------

def test_encoder_freeze_holds_joint_states(tmp_path):
    """While fault.encoder_freeze is on, axis/joint_states' screw joint holds; the truth moves."""
    sched = ('time,parameter,value\n0.1995,fault.encoder_freeze,true\n'
             '0.4,fault.encoder_freeze,false\n')
    out = _simulate(tmp_path, 'freeze', sched, 0.6, '--profile', 'sine', '--amplitude', 0.1,
                    '--frequency', 2.0, *SENSORS, *STEP_END, step_end=True)
    _meta, topics = _read_mcap(out)
    truth = _truth(topics['/sim/joint_states'])
    js = {_stamp(m) // DT_NS: m for _t, m in topics['/axis/joint_states']}
    assert sorted(js) == list(range(1, 601))
    # The freeze acts from step 200 (0.1995 s rounds up) up to step 399: the samples of
    # stamps 201..400 hold the reading of stamp 200 with velocity 0.
    held = js[200].position[0]
    for n in range(201, 401):
        assert js[n].position[0] == held and js[n].velocity[0] == 0.0, n
    # Live encoder (stamps up to 200 and from 401): reading = floor((q + noise) N / 2 pi)
    # counts, so |reading - true motor angle| <= one count + |noise|; |noise| < 6 sigma
    # (P ~ 2e-9 per sample, 400 samples). 1e-9 rad covers the rounding of ~300 rad angles.
    tol_enc = COUNT + 6.0 * ENC_NOISE + 1e-9
    for n in list(range(1, 201)) + list(range(401, 601)):
        assert abs(js[n].position[0] - truth[n * DT_NS][0][0]) <= tol_enc, n
    # The screw turns on: across the frozen window the truth moves many counts, and far more
    # than the live tolerance from the held value at its end and just after it.
    assert abs(truth[400 * DT_NS][0][1] - truth[200 * DT_NS][0][1]) > 100 * COUNT
    assert abs(truth[400 * DT_NS][0][0] - held) > 3 * tol_enc
    assert js[401].position[0] != held
    # The linear scale is not frozen: the nut joint tracks the truth throughout,
    # |reading - x| <= resolution + 6 sigma (1e-12 m: rounding of floor(x / r) r).
    tol_sc = RES + 6.0 * SCALE_NOISE + 1e-12
    for n in range(1, 601):
        assert abs(js[n].position[1] - truth[n * DT_NS][0][2]) <= tol_sc, n
    assert len({js[n].position[1] for n in range(201, 401)}) > 100


def test_state_drop_rate_binomial(tmp_path):
    """fault.state_drop_rate p loses a binomial share of joint_states; sim/joint_states has all."""
    p, k_on, k_off, duration = 0.3, 100, 1100, 1.2
    sched = f'time,parameter,value\n0.1,fault.state_drop_rate,{p}\n1.1,fault.state_drop_rate,0\n'
    out = _simulate(tmp_path, 'drop', sched, duration, *_inputs('velocity_csv', tmp_path),
                    *SENSORS)
    _meta, topics = _read_mcap(out)
    n_ticks = int(duration * 1000)
    all_stamps = set(range(1, n_ticks + 1))
    assert [_stamp(m) // DT_NS for _t, m in topics['/sim/joint_states']] == sorted(all_stamps)
    js = [(t // DT_NS, _stamp(m) // DT_NS) for t, m in topics['/axis/joint_states']]
    assert all(t == s for t, s in js)                    # no delay: logged at their stamp
    missing = all_stamps - {s for _t, s in js}
    # Steps k_on .. k_off - 1 (stamps k_on + 1 .. k_off) are subject to the loss, N of them.
    assert missing <= set(range(k_on + 1, k_off + 1)), sorted(missing)[:5]
    n = k_off - k_on
    mean, sigma = n * p, math.sqrt(n * p * (1.0 - p))
    # Binomial(N = 1000, p = 0.3): mean 300, sigma 14.5; 3 sigma is exceeded with P ~ 0.3 %.
    assert abs(len(missing) - mean) <= 3.0 * sigma, (len(missing), mean, sigma)
    # nut_position and /tf are lost with their axis/joint_states.
    assert [t // DT_NS for t, _m in topics['/nut_position']] == [t for t, _s in js]
    assert [t // DT_NS for t, _m in topics['/tf']] == [t for t, _s in js]


@pytest.mark.parametrize('sensors', ['ideal', 'quantised'])
def test_state_delay_stamps_and_values(sensors, tmp_path):
    """With state_delay d axis/joint_states logged at tick n carries stamp n - d and its truth."""
    sched = 'time,parameter,value\n0.3,state_delay,3\n0.6,state_delay,1\n'
    out = _simulate(tmp_path, 'delay', sched, 0.8, '--profile', 'sine', '--amplitude', 0.1,
                    '--frequency', 2.0, *(QUANTISED if sensors == 'quantised' else []),
                    *STEP_END, step_end=True)
    topics = _read_rosbags(out)
    truth = _truth(topics['/sim/joint_states'])
    assert sorted(truth) == [k * DT_NS for k in range(1, 801)]
    js = [(t, _stamp(m), m) for t, m in topics['/axis/joint_states']]
    # Every sample is delivered exactly once, in order; the last one (delay 1 at the end)
    # never is.
    assert [s for _t, s, _m in js] == [k * DT_NS for k in range(1, 800)]
    logs = [t // DT_NS for t, _s, _m in js]
    # 3 ticks from step 300 (first delayed sample: stamp 301, logged at 304), 1 from step 600.
    assert not {301, 302, 303} & set(logs)
    for t, s, _m in js:
        n = t // DT_NS
        if n <= 300:
            assert s == t, n
        elif 304 <= n <= 600:
            assert s == t - 3 * DT_NS, n
        elif n >= 604:
            assert s == t - 1 * DT_NS, n
    for t, s, m in js:
        (q_m, q_s, x), (w_m, w_s, v), (tq_m, _tq_s, f) = truth[s]
        # The efforts are no sensor readings: the motor torque and the axial force on nut A.
        assert list(m.effort) == [tq_m, f], s
        if sensors == 'ideal':
            # An ideal sensor reports the truth itself: the same doubles.
            assert list(m.position) == [q_s, x] and list(m.velocity) == [w_s, v], s
        else:
            # floor quantisation without noise: the reading lies within one count of the
            # true motor angle (the encoder is on the motor; 1e-9 rad: rounding of ~300 rad)
            # and 0 <= x - reading < r (1e-12 m: rounding of floor(x / r) r).
            assert abs(m.position[0] - q_m) < COUNT + 1e-9, s
            assert abs(m.position[0] / COUNT - round(m.position[0] / COUNT)) < 1e-6, s
            assert -1e-12 <= x - m.position[1] < RES + 1e-12, s
    # nut_position follows its axis/joint_states (same log times, same value).
    assert [(t, m.data) for t, m in topics['/nut_position']] == \
        [(t, m.position[1]) for t, _s, m in js]


def test_quantised_reading_at_its_stamp_default_drive_rate(tmp_path):
    """At the default drive_rate a noise-free quantised reading is within a count of its truth."""
    out = _simulate(tmp_path, 'default_rate', 'time,parameter,value\n', 0.5, '--profile', 'sine',
                    '--amplitude', 0.1, '--frequency', 2.0, *QUANTISED)
    _meta, topics = _read_mcap(out)
    truth = _truth(topics['/sim/joint_states'])
    # floor quantisation: |reading - true motor angle| < one count (1e-9 rad: rounding),
    # 0 <= x - reading < r (1e-12 m), if the reading is the truth at the stamp.
    worst_enc = max(abs(m.position[0] - truth[_stamp(m)][0][0])
                    for _t, m in topics['/axis/joint_states'])
    worst_sc = max(abs(m.position[1] - truth[_stamp(m)][0][2])
                   for _t, m in topics['/axis/joint_states'])
    assert worst_enc < COUNT + 1e-9 and worst_sc < RES + 1e-12, (worst_enc / COUNT,
                                                                 worst_sc / RES)


def test_jam_from_params_file(tmp_path):
    """A ROS 2 parameter file with nested fault: {jam, jam_position} is taken and recorded."""
    yaml = tmp_path / 'axis.yaml'
    yaml.write_text('/**:\n  ros__parameters:\n    fault:\n      jam: true\n'
                    '      jam_position: 0.001\n    encoder_counts: 4096\n')
    out = tmp_path / 'jam.mcap'
    v_cmd, duration = 0.01, 0.5
    cli_ok('simulate', '--params', yaml, '--velocity', v_cmd, '--duration', duration,
           '--output', out, '--quiet')
    meta, topics = _read_mcap(out)
    params = meta[PARAMS_RECORD][0]
    assert params['fault.jam'] == 'True'
    assert float(params['fault.jam_position']) == 0.001
    assert params['encoder_counts'] == '4096'
    assert params['preset'] == 'axis'
    # The jam blocks the nut (starting below it) on its way up. Upper bound of the
    # penetration from energy: the stop spring k absorbs the kinetic energy of the
    # drivetrain (M = moving mass + reflected inertia) at contact speed <= 2 v_cmd and the
    # work of the largest force the motor can push (F = T_max 2 pi / lead, plus gravity):
    # delta <= (2 F + sqrt(k M) 2 v_cmd) / k.
    g = {k: float(params[k]) for k in ('max_torque', 'pitch', 'starts', 'end_stop_stiffness',
                                       'payload_mass', 'nut_mass', 'motor_inertia',
                                       'screw_inertia', 'gravity')}
    lead = g['pitch'] * g['starts']
    mass = g['payload_mass'] + g['nut_mass']
    m_eff = mass + (g['motor_inertia'] + g['screw_inertia']) * (2 * math.pi / lead) ** 2
    force = g['max_torque'] * 2 * math.pi / lead + mass * g['gravity']
    k = g['end_stop_stiffness']
    bound = 0.001 + (2 * force + math.sqrt(k * m_eff) * 2 * v_cmd) / k
    x = [m.position[2] for _t, m in topics['/sim/joint_states']]
    # The commanded travel (5 mm) passes the jam, so the nut reaches it and stays there.
    assert 0.001 <= max(x) <= bound < v_cmd * duration, (max(x), bound)
    assert x[-1] >= 0.001


# ---------------------------------------------------------------------------
# 3. determinism
# ---------------------------------------------------------------------------

def _message_hash(path):
    """Return (count, sha256) of (topic, log time, data) of every message in file order."""
    from mcap.reader import make_reader
    h, n = hashlib.sha256(), 0
    with open(path, 'rb') as f:
        for _s, channel, message in make_reader(f).iter_messages(log_time_order=False):
            h.update(channel.topic.encode() + b'\0' + message.log_time.to_bytes(8, 'little')
                     + len(message.data).to_bytes(4, 'little') + message.data)
            n += 1
    return n, h.hexdigest()


@pytest.mark.parametrize('source', ['sine', 'velocity_csv'])
def test_same_command_line_same_file(source, tmp_path):
    """The same command line twice gives files with identical messages and update records."""
    args = [*_inputs(source, tmp_path), *SENSORS]
    a = _simulate(tmp_path, 'a', FULL_SCHEDULE, FULL_DURATION, *args)
    b = _simulate(tmp_path, 'b', FULL_SCHEDULE, FULL_DURATION, *args)
    ha, hb = _message_hash(a), _message_hash(b)
    assert ha == hb
    assert ha[0] > 4 * 800          # commands, states, truth, /tf of 800 ticks
    assert _read_mcap(a)[0][UPDATE_RECORD] == _read_mcap(b)[0][UPDATE_RECORD]


def test_sensor_seed_changes_readings_not_truth(tmp_path):
    """Another sensor_seed changes axis/joint_states, not the truth before seeded command loss."""
    args = _inputs('sine', tmp_path)
    a = _simulate(tmp_path, 'a', FULL_SCHEDULE, FULL_DURATION, *args, *SENSORS)
    b = _simulate(tmp_path, 'b', FULL_SCHEDULE, FULL_DURATION, *args, *SENSORS,
                  '--set', 'sensor_seed=8')
    ta, tb = (_truth(_read_mcap(p)[1]['/sim/joint_states']) for p in (a, b))
    # The torque input is open loop: no sensor reading acts on the axis, so the truth is the
    # same doubles until the first seed-dependent physical input, the command losses that
    # start at step 350 (stamp 351). That includes the first tick.
    assert ta[DT_NS] == tb[DT_NS]
    for n in range(1, 351):
        assert ta[n * DT_NS] == tb[n * DT_NS], n
    ja, jb = ({_stamp(m): list(m.position) for _t, m in _read_mcap(p)[1]['/axis/joint_states']}
              for p in (a, b))
    common = sorted(set(ja) & set(jb))
    differ = sum(ja[s] != jb[s] for s in common)
    # Two independent noise draws of sigma 1.3 counts (encoder) and 0.5 resolutions (scale)
    # give the same pair of readings with probability ~ 0.22 * 0.5 (same count of a
    # difference of sigma 1.8 counts: ~ 1 / (1.8 sqrt(2 pi)); likewise for the scale), so
    # ~ 90 % differ; half is far below (binomial sigma over ~500 stamps: ~1.3 %).
    assert len(common) > 400
    assert differ > 0.5 * len(common), (differ, len(common))
    # The state losses are seeded too: the two runs lose different stamps.
    assert set(ja) != set(jb)


# ---------------------------------------------------------------------------
# 4. bad schedules
# ---------------------------------------------------------------------------

BAD_SCHEDULES = {
    'unknown_parameter': ('time,parameter,value\n0.1,fault.jam,true\n0.2,fault.bogus,1\n', 3,
                          [r"unknown parameter 'fault\.bogus'"]),
    # the parameter, then the value (2, maybe printed 2.0), then the range [0, 1]
    'out_of_range': ('time,parameter,value\n0.1,fault.motor_torque_scale,2\n', 2,
                     [r"fault\.motor_torque_scale\W.*\b2(\.0*)?\b.*\[0(\.0*)?, 1(\.0*)?\]"]),
    'time_backwards': ('time,parameter,value\n0.3,fault.jam,true\n0.2,fault.jam,false\n', 3,
                       [r'\b0\.2\b.*backwards']),
    'read_only': ('time,parameter,value\n0.1,linear_scale,false\n', 2,
                  [r'linear_scale.*read-only']),
    'malformed_after_data': ('time,parameter,value\n0.1,fault.jam,true\n0.2,fault.jam\n', 3,
                             [r'expected "time,parameter,value"']),
    'malformed_first_data_line': ('time,parameter,value\n0.2;fault.jam;true\n'
                                  '0.3,fault.jam,false\n', 2,
                                  [r'expected "time,parameter,value"']),
}


@pytest.mark.parametrize('case', list(BAD_SCHEDULES))
def test_bad_schedule_one_error_line(case, tmp_path):
    """A bad schedule: non-zero exit, one error line naming the file, the line and the cause."""
    text, lineno, needles = BAD_SCHEDULES[case]
    faults = tmp_path / 'faults.csv'
    faults.write_text(text)
    out = tmp_path / 'never.mcap'
    r = cli('simulate', '--duration', 0.5, '--faults', faults, '--output', out, '--quiet')
    lines = r.stderr.strip().splitlines()
    assert r.returncode != 0, r.stdout + r.stderr
    assert 'Traceback' not in r.stderr and len(lines) == 1, r.stderr
    line = lines[0]
    assert 'error' in line and str(faults) in line and f'line {lineno}' in line, line
    for pattern in needles:
        assert re.search(pattern, line), (pattern, line)
    assert not out.exists()          # the schedule is checked before anything runs
