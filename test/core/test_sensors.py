"""
The axis's sensors (doc/model.md section 17), the truth values and the message faults' core parts.

Oracles:
- counting: a quantised reading is a whole number of counts, ``floor`` of the
  truth (in the q sense of the encoder, the +x sense of the scale);
- the noise model's statistics: mean, standard deviation and correlation of
  seeded Gaussian noise within 3 standard errors (the seeds are fixed, so
  each check is a deterministic test; 3 SE would be exceeded by an honest
  Gaussian source with probability 0.3 % per check);
- difference quotients and the first-order filter recomputed here from the
  readings, with the gain 1 - exp(-T_d / T_f) computed here;
- the backlash b: the dead band b / (r_m tan lambda) of motor angle in which a
  linear scale stands still after a reversal, and none through the encoder;
- binomial bounds N p +- 3 sqrt(N p (1 - p)) for the seeded message losses.

Readings are compared with the truth of the same tick. The kernel samples the
sensors for the drive at the end of every drive period (m substeps,
``drive.update_period(nsub, dt, drive_rate)``); a step whose end is no drive
sample reports readings taken at its end (``sensors.readings``). The tests of
the drive's samples themselves (velocity estimates, the noise sequence) set
``drive_rate`` to the update rate 1000 Hz, where m = nsub: one sample per
tick, at its end (asserted); the default 4000 Hz gives m = 5 for the 18
substeps of tr12x3, a period that does not divide the step.
"""
import math

import numpy as np
import pytest

from leadscrew_sim import LeadScrewModel, load_preset, ScrewParams
from leadscrew_sim.core.engine import drive as D
from leadscrew_sim.core.commands import CommandHold, DROPPED
from leadscrew_sim.core.delivery import lost_samples, StateDelivery
from leadscrew_sim.core.engine.sensors import STREAM_COMMAND_DROP, uniform

EPS = np.finfo(float).eps
DT = 1e-3
COUNTS = 4096
COUNT = 2.0 * math.pi / COUNTS         # one encoder count [rad]
RES = 1e-6                             # scale resolution [m]


def velocity_rows(omega):
    """Return velocity-mode command rows (theta sense) for the motor rates omega [rad/s]."""
    omega = np.asarray(omega, dtype=float)
    c = np.empty((len(omega), 4))
    c[:, 0] = D.MODE_VELOCITY
    c[:, 1] = math.nan
    c[:, 2] = omega
    c[:, 3] = math.nan
    return c


def nut_rate(m, v):
    """Return the motor rate [rad/s] that moves the nut of model m at v [m/s] (rigid)."""
    return float(m.nut_to_motor(v) - m.nut_to_motor(0.0))


def one_sample_per_tick(m):
    """Assert that model m samples its sensors for the drive once per tick, at its end."""
    assert D.update_period(m.nsub, m.dt, m.params.drive_rate) == m.nsub


def tr12(drive_rate=1000.0, **changes):
    """Return the tr12x3 preset, by default with the drive at the update rate (1 sample a tick)."""
    return load_preset('tr12x3').replace(drive_rate=drive_rate, **changes)


def assert_drive_samples(m):
    """Assert where model m samples for the drive: at every tick's end at 1000 Hz only."""
    m_sub = D.update_period(m.nsub, m.dt, m.params.drive_rate)
    assert (m_sub == m.nsub) == (m.params.drive_rate == 1000.0), (m.nsub, m_sub)


# 1. Quantisation ------------------------------------------------------------------------

@pytest.mark.parametrize('drive_rate', [1000.0, 4000.0])
@pytest.mark.parametrize('hand', ['right', 'left'])
def test_readings_are_whole_counts_and_the_floor_of_the_truth(hand, drive_rate):
    """Encoder and scale readings are whole counts, floor of the truth of the same tick."""
    p = tr12(drive_rate, hand=hand, encoder_counts=COUNTS, scale_resolution=RES)
    hs = p.hand_sign
    m = LeadScrewModel(p, dt=DT)
    assert_drive_samples(m)     # 4000 Hz: the step's end falls between drive samples
    t = np.arange(1500) * DT
    # out and back at up to 10 mm/s: 4.7 mm, some 6,000 counts of motor travel each way
    r = m.run(None, commands=velocity_rows(nut_rate(m, 0.01) * np.sin(2 * math.pi * t / 1.5)))
    assert np.ptp(r['nut_position']) > 4e-3
    a, x = r['sensor_screw_angle'], r['sensor_nut_position']
    k_enc, k_sc = a / COUNT, x / RES
    # a = k * COUNT rounded, then divided by COUNT: two roundings of eps / 2 relative, so
    # |a / COUNT - k| <= eps |k| (< 3e-11 for |k| < 1e5 counts); 1e-6 is far above that
    # and far below the 0.5 a non-integer reading could reach
    assert np.abs(k_enc).max() < 1e5
    assert np.abs(k_enc - np.round(k_enc)).max() < 1e-6
    assert np.abs(k_sc - np.round(k_sc)).max() < 1e-6
    # floor in the q sense (q = h theta) for the encoder, in +x for the scale; the product
    # x N / 2 pi (x / r) is rounded before the floor, so a reading may exceed the truth by
    # a few ulp of the value: 4 eps of the largest magnitude
    tol_a = 4 * EPS * np.abs(r['motor_angle']).max()
    tol_x = 4 * EPS * np.abs(r['nut_position']).max()
    d_enc = hs * (r['motor_angle'] - a)
    d_sc = r['nut_position'] - x
    assert d_enc.min() >= -tol_a and d_enc.max() < COUNT + tol_a
    assert d_sc.min() >= -tol_x and d_sc.max() < RES + tol_x
    # the readings are not the truth (the test sees a quantiser, not an ideal sensor)
    assert d_enc.max() > 0.5 * COUNT and d_sc.max() > 0.5 * RES
    # tick by tick through joint_values(), against truth_values() of the same tick
    m2 = LeadScrewModel(p, dt=DT)
    m2.command('velocity', velocity=nut_rate(m2, -0.01))
    for _ in range(200):
        m2.advance_held()
        jv, tv = m2.joint_values(), m2.truth_values()
        k = jv[0] / COUNT
        assert abs(k - round(k)) < 1e-6 and abs(jv[1] / RES - round(jv[1] / RES)) < 1e-6
        # the same 4 eps rounding allowance as above, with |theta| < 100 rad, |x| < 0.1 m
        assert -4e2 * EPS <= hs * (tv[0] - jv[0]) < COUNT + 4e2 * EPS
        assert -4e-1 * EPS <= tv[2] - jv[1] < RES + 4e-1 * EPS


# 2. Noise statistics ---------------------------------------------------------------------

N_NOISE = 40000
SIGMA_E, BIAS_E = 1e-3, 5e-4        # rad
SIGMA_S, BIAS_S = 2e-6, -3e-6       # m


def noisy_run(seed, hand='right', n=N_NOISE, drive_rate=1000.0):
    """Return the run of a self-locking tr12x3 held still at zero torque with noisy sensors."""
    p = tr12(drive_rate, hand=hand, encoder_noise=SIGMA_E, encoder_bias=BIAS_E,
             scale_noise=SIGMA_S, scale_bias=BIAS_S, sensor_seed=seed)
    assert p.self_locking
    m = LeadScrewModel(p, dt=DT)
    assert_drive_samples(m)
    return m.run(np.zeros(n))


@pytest.mark.parametrize('hand,drive_rate', [('right', 1000.0), ('left', 1000.0),
                                             ('right', 4000.0)])
def test_noise_mean_std_and_independence(hand, drive_rate):
    """Reading - truth: mean = bias, std = sigma within 3 SE; encoder and scale uncorrelated."""
    # 1000 Hz: the drive's samples; 4000 Hz: the readings a step takes at its end
    r = noisy_run(12345, hand, drive_rate=drive_rate)
    n = N_NOISE
    # self-locking at zero torque: the truth barely moves (it settles by nm on its seating),
    # and each reading is compared with the truth of its own tick anyway
    assert np.ptp(r['nut_position']) < 1e-7
    e = r['sensor_screw_angle'] - r['motor_angle']      # theta sense: bias + noise
    s = r['sensor_nut_position'] - r['nut_position']
    for z, sigma, bias in ((e, SIGMA_E, BIAS_E), (s, SIGMA_S, BIAS_S)):
        # 3 standard errors: sigma / sqrt(n) of the mean, sigma / sqrt(2 (n - 1)) of the
        # standard deviation of a Gaussian sample
        assert abs(z.mean() - bias) < 3 * sigma / math.sqrt(n)
        assert abs(z.std(ddof=1) - sigma) < 3 * sigma / math.sqrt(2 * (n - 1))
    # independent noises: the sample correlation has a standard error of 1 / sqrt(n)
    assert abs(np.corrcoef(e, s)[0, 1]) < 3 / math.sqrt(n)
    # and successive samples are uncorrelated too (a counter-based generator)
    assert abs(np.corrcoef(e[1:], e[:-1])[0, 1]) < 3 / math.sqrt(n)


def test_reported_noise_is_independent_from_tick_to_tick_at_a_slow_drive_rate():
    """At drive_rate 250 Hz (a sample every 4 ticks) successive reports have independent noise."""
    n = 20000
    r = noisy_run(12345, n=n, drive_rate=250.0)
    e = r['sensor_screw_angle'] - r['motor_angle']
    s = r['sensor_nut_position'] - r['nut_position']
    for z in (e, s):
        # the lag-1 sample correlation of independent samples: standard error 1 / sqrt(n)
        assert abs(np.corrcoef(z[1:], z[:-1])[0, 1]) < 3 / math.sqrt(n)


def test_same_seed_same_noise_other_seed_other_noise():
    """The same sensor_seed gives bit-identical readings; another seed another sequence."""
    n = 5000
    a, b, c = noisy_run(7, n=n), noisy_run(7, n=n), noisy_run(8, n=n)
    for key in ('sensor_screw_angle', 'sensor_nut_position', 'sensor_screw_velocity',
                'sensor_nut_velocity'):
        assert a[key].tobytes() == b[key].tobytes(), key
        # two independent continuous deviates are equal with probability 0
        assert np.count_nonzero(a[key] != c[key]) > 0.99 * n, key


def test_block_run_equals_tick_by_tick_with_noise():
    """model.run over all ticks and model.advance_held per tick give the same bits, noise on."""
    # the default drive rate: several samples per tick, a noisy feedback in the velocity loop
    p = load_preset('tr12x3').replace(encoder_counts=COUNTS, encoder_noise=2e-3,
                                      encoder_bias=1e-3, scale_resolution=RES, scale_noise=3e-6,
                                      scale_bias=1e-6, velocity_filter_time=2e-3, sensor_seed=99)
    a, b = LeadScrewModel(p, dt=DT), LeadScrewModel(p, dt=DT)
    assert D.update_period(a.nsub, DT, p.drive_rate) < a.nsub
    omega = nut_rate(a, 0.005) * np.sin(np.arange(600) * 0.01)
    r = a.run(None, commands=velocity_rows(omega))
    keys = ('sensor_screw_angle', 'sensor_nut_position', 'sensor_screw_velocity',
            'sensor_nut_velocity', 'motor_torque', 'axial_force')
    for k, w in enumerate(omega):
        b.command('velocity', velocity=float(w))
        b.advance_held()
        got = b.joint_values()
        want = (r['sensor_screw_angle'][k], r['sensor_nut_position'][k],
                r['sensor_screw_velocity'][k], r['sensor_nut_velocity'][k],
                r['motor_torque'][k], r['axial_force'][k])
        assert [np.float64(g).tobytes() for g in got] == \
            [np.float64(x).tobytes() for x in want], (k, keys)
    assert a.state.tobytes() == b.state.tobytes()


# 3. Velocity estimate ---------------------------------------------------------------------

@pytest.mark.parametrize('filter_time', [0.0, 5e-3])
def test_velocity_is_the_filtered_difference_quotient_of_the_readings(filter_time):
    """Sensor velocities are (r_k - r_k-1) / T_d through v_f += beta (v_raw - v_f)."""
    p = tr12(encoder_counts=COUNTS, scale_resolution=RES, velocity_filter_time=filter_time)
    m = LeadScrewModel(p, dt=DT)
    one_sample_per_tick(m)       # so T_d is the step dt and each tick carries every sample
    td = DT
    j0 = m.joint_values()        # the readings at reset (velocities 0)
    n = 1500
    r = m.run(None, commands=velocity_rows(nut_rate(m, 0.01) * np.sin(np.arange(n) * 0.01)))
    for pos, vel in (('sensor_screw_angle', 'sensor_screw_velocity'),
                     ('sensor_nut_position', 'sensor_nut_velocity')):
        readings = np.concatenate([[j0[0] if pos == 'sensor_screw_angle' else j0[1]], r[pos]])
        raw = np.diff(readings) / td
        assert np.count_nonzero(raw) > n // 2           # the axis moves
        if filter_time == 0.0:
            # the kernel forms v_prev + 1 (raw - v_prev): two roundings of eps / 2 relative
            # to |raw| + |v_prev|; its T_d = m (dt / nsub) may differ from dt by an ulp
            prev = np.concatenate([[0.0], raw[:-1]])
            tol = 2 * EPS * (np.abs(raw) + np.abs(prev))
            assert (np.abs(r[vel] - raw) <= tol).all(), vel
        else:
            beta = 1.0 - math.exp(-td / filter_time)
            vf, out = 0.0, np.empty(n)
            for k in range(n):
                vf = vf + beta * (raw[k] - vf)
                out[k] = vf
            # the filter contracts by (1 - beta) per sample, so rounding differences of a few
            # eps |v| per sample sum to at most a few eps |v| / beta (beta = 0.18 here): 1e-13
            assert np.abs(r[vel] - out).max() <= 1e-13 * np.abs(out).max(), vel
            # an unfiltered estimate would miss the oracle by the filter's lag, far beyond
            assert np.abs(r[vel] - raw).max() > 0.1 * np.abs(raw).max(), vel


# 4. Ideal defaults --------------------------------------------------------------------------

def bits(values):
    """Return the float64 bytes of each value (bit-for-bit comparison)."""
    return [np.float64(v).tobytes() for v in values]


@pytest.mark.parametrize('preset', ['tr12x3', 'anti_backlash'])
@pytest.mark.parametrize('hand', ['right', 'left'])
def test_ideal_sensors_report_the_step_output_bit_for_bit(preset, hand):
    """Default sensors: joint_values() and truth_values() are the StepOutput fields, bitwise."""
    p = ScrewParams.from_dict({'hand': hand}, base=load_preset(preset))
    m = LeadScrewModel(p, dt=DT)
    twin = LeadScrewModel(p, dt=DT)
    torques = 0.3 * np.sin(0.2 * np.arange(60)) * p.max_torque
    r = twin.run(torques)
    lam = p.lead_angle
    for k, tq in enumerate(torques):
        m.advance(float(tq))
        o = m.output()
        jv, tv = m.joint_values(), m.truth_values()
        assert all(type(v) is float for v in jv + tv)
        assert bits(jv) == bits((o.screw_angle, o.nut_position, o.screw_velocity,
                                 o.nut_velocity, o.motor_torque, o.axial_force))
        assert bits(tv[:7] + tv[8:10] + tv[12:]) == bits(
            (o.motor_angle, o.screw_angle, o.nut_position, o.nut_b_position, o.motor_velocity,
             o.screw_velocity, o.nut_velocity, o.motor_torque, o.thread_torque, o.axial_force))
        # nut B's rate: that of nut A without a split nut, else the run's column of the twin
        assert bits(tv[7:8]) == bits((o.nut_velocity if not p.anti_backlash
                                      else r['nut_b_velocity'][k],))
        # nut A's axial force from its flank forces and friction, (N_l - N_t) cos(lambda) +
        # F_f sin(lambda), formed here: a few roundings of the terms, 8 eps of their size
        size = abs(o.normal_leading) + abs(o.normal_trailing) + abs(o.friction_force)
        f_a = (o.normal_leading - o.normal_trailing) * math.cos(lam) + \
            o.friction_force * math.sin(lam)
        assert abs(tv[10] - f_a) <= 8 * EPS * size
        # the two nut forces add up to the axial force (one rounding of the difference)
        assert abs(tv[10] + tv[11] - tv[12]) <= 2 * EPS * (abs(tv[10]) + abs(tv[12]))
        if not p.anti_backlash:   # no half-nut B: it carries no force (to rounding)
            assert abs(tv[11]) <= 2 * EPS * abs(tv[12])
    assert any(v != 0.0 for v in jv)
    # the run's sensor columns are its truth columns, bit for bit
    for sensor, truth in (('sensor_screw_angle', 'screw_angle'),
                          ('sensor_nut_position', 'nut_position'),
                          ('sensor_screw_velocity', 'screw_velocity'),
                          ('sensor_nut_velocity', 'nut_velocity')):
        assert r[sensor].tobytes() == r[truth].tobytes(), sensor


# 5. Backlash visibility ----------------------------------------------------------------------

B = 2e-4            # backlash [m]
F_GUIDE = 20.0      # guide Coulomb force [N]: stops the nut when the flank leaves it


def reversal_run(**changes):
    """
    Run a horizontal tr12x3 out at 2 mm/s and back at 0.2 mm/s; return (model, run, i_rev).

    The velocity command ramps through zero over 0.11 s: the nut decelerates with
    the motor on its flank (0.02 m/s^2 against the guide's F_GUIDE / m = 2 m/s^2),
    so it is at rest when the motor reverses and does not coast into the gap. The
    slow return moves the motor by 0.2 um of nut travel per tick, the resolution
    of the dead band's end. i_rev is the tick of the motor's turning point.
    """
    p = tr12(inclination=0.0, backlash=B, guide_viscous=0.0, guide_coulomb=F_GUIDE, **changes)
    m = LeadScrewModel(p, dt=DT)
    one_sample_per_tick(m)
    t = np.arange(2000) * DT
    r = m.run(None, commands=velocity_rows(nut_rate(m, 0.002) * np.clip((0.5 - t) / 0.1,
                                                                        -0.1, 1.0)))
    motor_nut = m.motor_to_nut(r['motor_angle'])       # the motor angle in nut terms [m]
    i_rev = int(np.argmax(motor_nut))
    assert 300 < i_rev < 700 and motor_nut[i_rev] - motor_nut[-1] > 1.2 * B
    return m, r, i_rev


@pytest.mark.parametrize('counts', [0, COUNTS])
def test_without_a_scale_the_nut_reading_reverses_with_the_motor(counts):
    """linear_scale false: the nut reading is the encoder through the lead, no dead band."""
    m, r, i = reversal_run(linear_scale=False, encoder_counts=counts)
    rt = m.params.r_m * math.tan(m.params.lead_angle)
    rep, truth, theta = r['sensor_nut_position'], r['nut_position'], r['motor_angle']
    # its change is r_m tan(lambda) times the (true) motor angle change, within one count
    # of the encoder (lead / N in nut terms; 0 for the ideal encoder) and rounding
    count_x = rt * COUNT if counts else 0.0
    d_rep = rep - rep[i]
    d_motor = m.params.hand_sign * (theta - theta[i]) * rt
    assert np.abs(d_rep - d_motor).max() <= count_x + 1e-12
    # ... while the true nut stands still: when the motor has turned back by half the gap
    # (b / 2 in nut terms) the reading has followed it, the nut has not moved
    j = i + int(np.argmax(d_motor[i:] < -0.5 * B))
    assert d_rep[j] <= -0.5 * B + count_x
    # the nut at most coasts on after the turning point: from 2 mm/s against the guide's
    # F_GUIDE / m = 2 m/s^2 that is v^2 / (2 a) = 1 um, 1 % of the reading's b / 2
    m_nut = m.params.nut_mass + m.params.payload_mass
    assert abs(truth[j] - truth[i]) < 0.002 ** 2 / (2 * F_GUIDE / m_nut)
    # the backlash is invisible: reading - truth shifts by the whole gap across the
    # reversal, b plus the flank deflections 2 F_GUIDE / k (0.4 um), within a count
    shift = (rep[i] - truth[i]) - (rep[-1] - truth[-1])
    defl = 2 * F_GUIDE / m.params.contact_stiffness
    assert B - count_x - 1e-9 <= shift <= B + 1.25 * defl + count_x, shift


@pytest.mark.parametrize('res', [0.0, RES])
def test_a_linear_scale_stands_still_through_the_backlash_dead_band(res):
    """linear_scale true: the nut reading stays still for b 2 pi / lead of motor angle."""
    m, r, i = reversal_run(linear_scale=True, scale_resolution=res)
    p = m.params
    rep, truth, theta = r['sensor_nut_position'], r['nut_position'], r['motor_angle']
    dead_band = p.backlash / (p.r_m * math.tan(p.lead_angle))     # [rad] of motor angle
    assert dead_band == pytest.approx(B * 2 * math.pi / p.lead, rel=1e-12)
    # the first tick whose reading differs from the one at the turning point (by more than
    # round-off; a quantised reading changes by whole resolutions)
    j = i + int(np.argmax(np.abs(rep[i:] - rep[i]) > max(0.5 * res, 1e-12)))
    turned = abs(theta[j] - theta[i])
    # lower bound: the nut cannot move before the far flank reaches it, b of travel (the
    # flank that pushed it first relaxes its deflection: more, not less); upper bound: the
    # far flank must build the guide force F_GUIDE / k of deflection, the near one had it
    # (25 % margin for the contact damping of the slow approach), the nut must cross up to
    # one resolution before the reading changes, and the reading is seen once per tick
    step = np.abs(np.diff(theta[i:j + 2])).max()
    k_rt = 1.0 / (p.r_m * math.tan(p.lead_angle))                  # rad per m of nut
    defl = 2 * F_GUIDE / p.contact_stiffness
    assert dead_band - 1e-9 * k_rt <= turned <= dead_band + (1.25 * defl + res) * k_rt + step, \
        (turned, dead_band)
    # and the reading then follows the nut back
    assert rep[-1] < rep[i] - 0.2 * B
    # the truth topic's nut position agrees with the scale within one resolution (floor:
    # 0 <= truth - reading < r; the ideal scale is the truth, bit for bit)
    if res == 0.0:
        assert rep.tobytes() == truth.tobytes()
    else:
        tol = 4 * EPS * np.abs(truth).max()      # the rounding allowance of the floor test
        assert (truth - rep).min() >= -tol and (truth - rep).max() < res + tol


# 6. State delivery -------------------------------------------------------------------------

def values_of(k):
    """Return a distinct joint value tuple for tick k."""
    return (float(k), 0.5 * k, -1.0 * k, 2.0, 3.0, 4.0)


@pytest.mark.parametrize('delay', [0, 1, 7])
def test_state_delay_delivers_each_sample_delay_ticks_late_with_its_stamp(delay):
    """Sample k is delivered at the end of tick k + state_delay, stamped with its own time."""
    d = StateDelivery(ScrewParams(state_delay=delay))
    delivered = {}
    for tick in range(100):
        d.sample(tick, tick * 1_000_000, values_of(tick))
        for stamp, values in d.due(tick):
            delivered.setdefault(tick, []).append((stamp, values))
    # every tick from delay on delivers exactly the sample of delay ticks ago
    assert sorted(delivered) == list(range(delay, 100))
    for tick, got in delivered.items():
        k = tick - delay
        assert got == [(k * 1_000_000, values_of(k))]
    assert d.pending() == (delay > 0) and d.dropped == 0


def test_state_drop_rate_loses_a_binomial_share_as_lost_samples_says():
    """fault.state_drop_rate p loses N p +- 3 sigma of N samples, those lost_samples() names."""
    n, rate, seed = 20000, 0.3, 4242
    p = ScrewParams(fault_state_drop_rate=rate, sensor_seed=seed, state_delay=2)
    d = StateDelivery(p)
    got = set()
    for tick in range(n + 2):
        if tick < n:
            d.sample(tick, tick, values_of(tick))
        got.update(stamp for stamp, _v in d.due(tick))
    lost = np.array([k not in got for k in range(n)])
    # binomial: mean N p, standard deviation sqrt(N p (1 - p)) = 65 of 6000
    assert abs(lost.sum() - n * rate) < 3 * math.sqrt(n * rate * (1 - rate))
    assert d.dropped == lost.sum()
    assert (lost_samples(seed, rate, 0, n) == lost).all()
    assert (lost_samples(seed, rate, 5000, 100) == lost[5000:5100]).all()   # any block
    # the same seed loses the same samples; another seed others
    again = StateDelivery(p)
    lost2 = []
    for tick in range(n):
        before = again.dropped
        again.sample(tick, tick, values_of(tick))
        lost2.append(again.dropped > before)
    assert (np.array(lost2) == lost).all()
    other = lost_samples(seed + 1, rate, 0, n)
    # two independent Bernoulli(p) sequences differ in 2 p (1 - p) N = 8400 places
    assert abs(np.count_nonzero(other != lost) - 2 * rate * (1 - rate) * n) < \
        3 * math.sqrt(n * 2 * rate * (1 - rate) * (1 - 2 * rate * (1 - rate)))


# 7. Command delay and loss -----------------------------------------------------------------

MS = 1_000_000


@pytest.mark.parametrize('delay', [0, 1, 5])
def test_command_delay_returns_a_command_delay_calls_later(delay):
    """A command given before step k is returned by changed_command at call k + command_delay."""
    hold = CommandHold(params=ScrewParams(command_delay=delay))
    given = {3: 0.1, 4: 0.2, 10: -0.3}           # step -> torque command given before it
    out = []
    for k in range(20):
        if k in given:
            assert hold.torque_command(given[k], k * MS) is None
        out.append(hold.changed_command(k * MS))
    # the first call hands over the initial command (torque mode, 0 N m), like one given
    # before step 0
    expect = [None] * 20
    for k, value in {0: 0.0, **given}.items():
        expect[k + delay] = (D.MODE_TORQUE, value)
    assert [None if c is None else (c[0], c[3]) for c in out] == expect


def test_command_drop_rate_loses_a_binomial_share_and_leaves_the_held_command():
    """fault.command_drop_rate p drops N p +- 3 sigma; a dropped command changes nothing."""
    n, rate, seed = 20000, 0.25, 31337
    hold = CommandHold(params=ScrewParams(fault_command_drop_rate=rate, sensor_seed=seed))
    hold.changed_command(0)
    held = hold.torque
    dropped = []
    for i in range(n):
        value = 1e-3 * (i + 1)
        reason = hold.torque_command(value, i * MS)
        changed = hold.changed_command(i * MS)
        if reason == DROPPED:
            dropped.append(i)
            assert hold.torque == held and changed is None     # nothing changed
        else:
            assert reason is None and hold.torque == value and changed[3] == value
            held = value
    # binomial: N p = 5000, 3 sigma = 184
    assert abs(len(dropped) - n * rate) < 3 * math.sqrt(n * rate * (1 - rate))
    assert hold.dropped == len(dropped) and hold.received == n
    # the documented rule: the n-th command is lost when uniform(seed, 3, n) < rate
    assert dropped == [i for i in range(n) if uniform(seed, STREAM_COMMAND_DROP, i) < rate]


def test_every_drive_command_kind_is_dropped_but_never_external_force():
    """At drop rate 1 every drive command is lost; external_force is never dropped."""
    hold = CommandHold(params=ScrewParams(fault_command_drop_rate=1.0))
    assert hold.torque_command(0.5, 0) == DROPPED
    assert hold.velocity_command(0.01, 0) == DROPPED
    assert hold.position_command(0.01, 0) == DROPPED
    assert hold.joint_commands(['screw_joint'], [1.0], [], [], 0) == (DROPPED, DROPPED)
    assert (hold.mode, hold.effort, hold.cmd_time) == (D.MODE_TORQUE, 0.0, None)
    assert hold.external_force(12.5) is None and hold.force == 12.5
    assert hold.received == 4 and hold.dropped == 4      # the force is not counted
    # the force does not consume a drop decision: the drive commands' counter is unchanged
    seed, rate = 5, 0.5
    a = CommandHold(params=ScrewParams(fault_command_drop_rate=rate, sensor_seed=seed))
    b = CommandHold(params=ScrewParams(fault_command_drop_rate=rate, sensor_seed=seed))
    ra, rb = [], []
    for i in range(200):
        ra.append(a.torque_command(0.1, i))
        b.external_force(float(i))
        rb.append(b.torque_command(0.1, i))
    assert ra == rb and DROPPED in ra and None in ra
