"""
Injected faults at the model level (fault.* parameters, doc/model.md sections 16-17).

Oracles:
- the quasi-static thread closed forms of :mod:`leadscrew_sim.core.geometry`
  (Shigley's raise torque): the thrust a torque gives through a sliding or a
  stuck thread, and the breakaway torque of a vertical load;
- the jam as a linear end stop: static penetration = force / stiffness, from
  the nut's equilibrium at rest;
- the drive's rules (drive.py): the following error is measured on the
  feedback, the torque-limit timer counts saturated updates, a latched fault
  switches the torque off, which then decays with the motor lag
  exp(-t / tau_e);
- bit-for-bit comparison of two runs with the same inputs.

Faults are switched with ``set_params`` between blocks of steps, as the node
does on a parameter change.
"""
import math

import numpy as np
import pytest

from leadscrew_sim import LeadScrewModel, load_preset, ScrewParams
from leadscrew_sim.core.engine import drive as D
from leadscrew_sim.core import geometry as G
from leadscrew_sim.core.commands import CommandHold, DROPPED
from leadscrew_sim.core.delivery import StateDelivery

EPS = np.finfo(float).eps
DT = 1e-3
COUNTS = 4096
COUNT = 2.0 * math.pi / COUNTS
RES = 1e-6
JAM = 0.005         # jam position [m]


def rows(mode, n, position=math.nan, velocity=math.nan, effort=math.nan):
    """Return n drive command rows, theta sense; the arguments broadcast."""
    c = np.empty((n, 4))
    c[:, 0], c[:, 1], c[:, 2], c[:, 3] = mode, position, velocity, effort
    return c


def nut_rate(m, v):
    """Return the motor rate [rad/s] that moves the nut of model m at v [m/s] (rigid)."""
    return float(m.nut_to_motor(v) - m.nut_to_motor(0.0))


def thrust(p, torque, mu):
    """Return the axial force [N] a torque drives through the thread with friction mu (raise)."""
    return torque / G.raise_torque(1.0, p.r_m, mu * p.thread_factor, p.lead_angle,
                                   p.collar_mu, p.collar_radius)


def horizontal(**changes):
    """Return tr12x3 laid horizontal, no load on the flanks, with the drive at 1000 Hz."""
    return load_preset('tr12x3').replace(inclination=0.0, drive_rate=1000.0, **changes)


# 1. Jam ----------------------------------------------------------------------------------

def jam_bounds(p):
    """Return (lo, hi) of the static jam penetration [m] under the drive's max torque."""
    # at rest the thread is stuck, its friction at most mu_s: the screw's torque balance
    # gives at least the thrust of mu_s; the thrust of the sliding approach is at most
    # that of the lowest friction coefficient of the Stribeck law, mu_k (mu_viscous 0)
    assert p.mu_viscous == 0.0 and p.mu_k < p.mu_s
    return (thrust(p, p.max_torque, p.mu_s) / p.end_stop_stiffness,
            thrust(p, p.max_torque, p.mu_k) / p.end_stop_stiffness)


def settled_against_the_jam(m, r):
    """Assert the nut of run r rests on the jam of model m; return its penetration [m]."""
    p = m.params
    pen = abs(r['nut_position'][-1] - JAM)
    assert abs(r['nut_velocity'][-1]) < 1e-9 and r['stuck'][-1]
    # the drive pushes with all it has (the velocity loop is saturated)
    assert abs(r['motor_torque'][-1]) == p.max_torque
    # the nut's equilibrium at rest: the jam's spring carries the axial thread force (the
    # damper and the guide's viscous force act on 1e-9 m/s: < 1e-5 N)
    assert abs(p.end_stop_stiffness * pen - abs(r['nut_force'][-1])) < 1e-5
    return pen


def test_jam_stops_the_nut_at_the_jam_plus_the_thrust_over_the_stop_stiffness():
    """fault.jam: the nut stops at jam + F / k_es, F the thrust of max_torque; one side only."""
    p = ScrewParams.from_dict({'fault': {'jam': True, 'jam_position': JAM}}, base=horizontal())
    m = LeadScrewModel(p, dt=DT)
    lo, hi = jam_bounds(p)
    # the velocity loop's integral builds the torque up over some 0.2 s once the nut stops,
    # ten times the 20 ms period of the axis on the jam's spring: a quasi-static load that
    # does not overshoot the sliding thrust
    r = m.run(None, commands=rows(D.MODE_VELOCITY, 2500, velocity=nut_rate(m, 0.005)))
    pen = settled_against_the_jam(m, r)
    assert r['nut_position'][-1] > JAM and lo <= pen <= hi, (pen, lo, hi)
    assert r['nut_position'][1000] > 0.004            # it got there at the commanded speed
    # the jam blocks only toward +x: backing off is free
    r = m.run(None, commands=rows(D.MODE_VELOCITY, 1000, velocity=nut_rate(m, -0.005)))
    assert r['nut_position'][-1] < JAM - 2e-3       # 5 mm/s for 1 s, less the loop's turn


def test_jammed_position_ramp_latches_the_following_error():
    """A position ramp into the jam latches FAULT_FOLLOWING_ERROR when |target - fb| > limit."""
    fel = 2 * math.pi
    p = ScrewParams.from_dict({'fault.jam': True, 'fault.jam_position': JAM,
                               'following_error_limit': fel}, base=horizontal())
    m = LeadScrewModel(p, dt=DT)
    assert D.update_period(m.nsub, DT, p.drive_rate) == m.nsub    # one drive update per tick
    n = 1500
    xs = np.arange(1, n + 1) * DT * 0.01                           # 10 mm/s to 15 mm
    theta = m.nut_to_motor(xs)
    theta0 = m.output().motor_angle
    r = m.run(None, commands=rows(D.MODE_POSITION, n, position=theta,
                                  velocity=np.gradient(theta, DT)))
    k = int(np.argmax(r['fault'] != D.FAULT_NONE))
    assert r['fault'][k] == D.FAULT_FOLLOWING_ERROR and (r['fault'][k:] != 0).all()
    assert m.drive_status()['fault'] == D.FAULT_FOLLOWING_ERROR
    # the update at the start of tick i compares target i with the (ideal) encoder's sample
    # at the end of tick i - 1: the limit is first exceeded at tick k (the same subtraction
    # as the drive's, negated for the right hand: exact, no tolerance)
    before = np.concatenate([[theta0], r['motor_angle'][:-1]])
    err = np.abs(theta - before)
    assert err[k] > fel and (err[:k] <= fel).all()
    # when it latched the nut was held at the jam: 10 mm/s into the stop rings past the
    # static penetration (< 0.08 mm) and the self-locking thread may keep some of it, but the
    # free nut would have followed the ramp for millimetres; 1 mm tells the two apart
    assert JAM < r['nut_position'][k] and r['nut_position'].max() < JAM + 1e-3
    assert xs[k] > JAM + 2e-3
    assert (r['motor_torque'][k + 1:] == 0.0).all()                 # torque off


# 2. Encoder freeze -------------------------------------------------------------------------

def frozen_move(**changes):
    """Hold a horizontal tr12x3 in position, freeze the encoder, command a 1 rad move; run 600."""
    # the runaway would latch the preset's overspeed trip first: off (max_screw_velocity 0)
    p = horizontal(following_error_limit=2.0, max_screw_velocity=0.0, **changes)
    m = LeadScrewModel(p, dt=DT)
    theta0 = m.output().motor_angle
    m.run(None, commands=rows(D.MODE_POSITION, 300, position=theta0))
    assert abs(m.output().motor_angle - theta0) < 1e-9
    m.set_params(p.replace(fault_encoder_freeze=True))
    frozen = m.joint_values()[0]
    r = m.run(None, commands=rows(D.MODE_POSITION, 600, position=theta0 + 1.0))
    return m, r, theta0, frozen


def test_frozen_encoder_runaway_is_caught_by_the_torque_limit_time_not_the_following_error():
    """A frozen encoder's runaway is caught by torque_limit_time, not by the following error."""
    # The drive measures its following error on the frozen reading: it stays at the
    # commanded 1 rad (under the 2 rad limit) while the true error grows without bound;
    # the velocity feedback reads 0, so the loop's torque saturates and stays saturated
    # until torque_limit_time latches FAULT_TORQUE_LIMIT.
    tlt = 0.05
    m, r, theta0, frozen = frozen_move(torque_limit_time=tlt)
    k = int(np.argmax(r['fault'] != D.FAULT_NONE))
    assert r['fault'][k] == D.FAULT_TORQUE_LIMIT and (r['fault'][k:] != 0).all()
    assert (r['sensor_screw_angle'] == frozen).all()
    # the drive's error: the target less the frozen reading (theta sense), to rounding
    fe = r['following_error'][:k]
    assert np.abs(fe - (theta0 + 1.0 - frozen)).max() < 1e-12 and np.abs(fe).max() < 2.0
    # the true error passed the limit long before the fault (the runaway the drive missed)
    true_err = np.abs(theta0 + 1.0 - r['motor_angle'])
    assert true_err[k] > 10 * 2.0 and np.argmax(true_err > 2.0) < k - 10
    # the fault comes tlt after the saturation began; the timer adds a drive period (1 ms
    # here) at each saturated update, counting the period it starts, so it latches within
    # one period of tlt
    hit = int(np.argmax(np.abs(r['drive_torque']) >= m.params.max_torque))
    assert round(tlt / DT) - 1 <= k - hit <= round(tlt / DT) + 1
    assert (r['motor_torque'][k + 1:] == 0.0).all()


def test_frozen_encoder_runaway_loses_its_thrust_at_a_limit_switch():
    """A frozen-encoder runaway loses its thrust at the limit switch: it coasts, unpowered."""
    # The switch cuts the drive's torque toward its side (as it does in torque mode), so
    # the wrong feedback cannot push the nut on. The drive cannot brake a motion it does
    # not see, so the axis coasts on its kinetic energy (about 0.45 J of rotor at the
    # velocity limit) into the end stop, where a self-locking thread may wedge: that is
    # the crash a real axis needs its brake or safe torque off for.
    m, r, theta0, _frozen = frozen_move(torque_limit_time=0.05, limit_min_position=-0.01)
    p = m.params
    k = int(np.argmax(r['limit_min']))
    assert r['limit_min'][k] and r['nut_position'][k] <= -0.01
    # a torque toward -x is -hand_sign * theta-torque < 0 in the q sense (x = r tan(l) q);
    # from the drive update after the trip neither the command nor the applied torque
    # (no lag here) points that way
    assert not (p.hand_sign * r['drive_torque'][k + 2:] < 0.0).any()
    assert not (p.hand_sign * r['motor_torque'][k + 2:] < 0.0).any()
    # without the switch the same runaway keeps its thrust toward -x (the check can fail)
    m2, r2, _t, _f = frozen_move(torque_limit_time=0.0)
    assert (p.hand_sign * r2['drive_torque'][k + 2:] < 0.0).all()


# 3. Weakened motor -------------------------------------------------------------------------

def vertical_screw(**kw):
    """Return the vertical 10 kg axis of test_physics' breakaway tests."""
    base = dict(major_diameter=0.012, pitch=0.003, starts=1, mu_s=0.2, mu_k=0.15,
                payload_mass=10.0, nut_mass=0.2, inclination=math.pi / 2, guide_viscous=0.0,
                bearing_viscous=0.0, max_torque=5.0)
    base.update(kw)
    return ScrewParams(**base)


@pytest.mark.parametrize('scale', [1.0, 0.5])
def test_weakened_motor_breakaway_command_is_the_closed_form_over_the_scale(scale):
    """fault.motor_torque_scale s: the command at which the load lifts is T_breakaway / s."""
    p = vertical_screw(fault_motor_torque_scale=scale)
    closed = G.raise_torque(p.moving_mass * p.gravity, p.r_m, p.mu_s * p.thread_factor,
                            p.lead_angle)
    m = LeadScrewModel(p, dt=DT)
    m.run(np.zeros(200))                                  # settle on the seating
    step = closed / scale / 1000.0
    # the ramp straddles the closed form by half a step (0.05 %): no tie to round
    cmd = -(np.arange(2000) + 0.5) * step                 # -theta raises a right-hand nut
    r = m.run(cmd)
    # the motor delivers s times the command (no lag: one rounding of the lag update)
    assert np.abs(r['motor_torque'] - scale * cmd).max() <= 2 * EPS * np.abs(cmd).max()
    k = int(np.argmax(~r['stuck'] & (r['nut_velocity'] > 0.0)))
    assert not r['stuck'][k] and r['stuck'][:k].all()
    # quasi-static: the first step past the closed form breaks away, within one ramp step
    assert closed / scale < -cmd[k] <= closed / scale + step, (-cmd[k], closed / scale)


def test_weakened_motor_below_the_breakaway_never_lifts_the_load():
    """With s * max_torque below the breakaway torque the load never moves at full command."""
    p0 = vertical_screw()
    closed = G.raise_torque(p0.moving_mass * p0.gravity, p0.r_m, p0.mu_s * p0.thread_factor,
                            p0.lead_angle)
    s = 0.9 * closed / p0.max_torque
    m = LeadScrewModel(p0.replace(fault_motor_torque_scale=s), dt=DT)
    x0 = m.output().nut_position
    # ramp to twice max_torque (saturated from halfway; a ramp, so no step load rings the
    # flank spring past the static friction), then hold for a second
    cmd = -2.0 * p0.max_torque * np.minimum(np.arange(1, 2001) / 1000.0, 1.0)
    r = m.run(cmd)
    assert r['motor_torque'][-1] == pytest.approx(-s * p0.max_torque, rel=2 * EPS)
    assert r['stuck'][1:].all()
    # stuck, at rest: the axial thread force is the weight W; the flank force F_l carries it
    # with the friction F_f's help or against it, F_l (1 +- mu'_s tan(lambda)) = W at most, so
    # the flank deflection F_l / k changes by less than 2 mu'_s tan(lambda) W / (1 - ..) / k
    mt = p0.mu_s * p0.thread_factor * math.tan(p0.lead_angle)
    w = p0.moving_mass * p0.gravity
    assert np.abs(r['nut_position'] - x0).max() < 2 * mt * w / (1 - mt) / p0.contact_stiffness
    # the same command at full strength lifts it
    full = LeadScrewModel(p0, dt=DT).run(cmd)
    assert full['nut_position'][-1] > x0 + 1e-3


# 4. Injected drive fault ----------------------------------------------------------------------

def test_injected_fault_latches_cuts_the_torque_and_clears_only_once_off():
    """fault.drive_fault latches FAULT_INJECTED, torque decays as exp(-t / tau); clear once off."""
    tau = 2e-3
    p = load_preset('tr12x3').replace(torque_lag=tau, drive_rate=1000.0)
    assert p.self_locking
    m = LeadScrewModel(p, dt=DT)
    theta0 = m.output().motor_angle
    target = theta0 - 40.0                                # -theta raises the load
    m.command('position', position=target)
    for _ in range(10):                                   # under way, with torque
        m.advance_held()
    te0 = m.output().motor_torque
    assert abs(te0) > 0.01                              # a torque to watch decay
    m.set_params(ScrewParams.from_dict({'fault.drive_fault': True}, base=p))
    torques = []
    for k in range(20):
        m.advance_held()
        st = m.drive_status()
        assert st['fault'] == D.FAULT_INJECTED and st['drive_torque'] == 0.0
        torques.append(m.output().motor_torque)
    # the drive's first update of the tick (m = nsub: its first substep) sets the command to
    # 0; the lag then decays the applied torque by exp(-dt / tau) per tick; each substep's
    # update rounds (20 ticks of 18 substeps: < 1e-13 relative)
    decay = te0 * np.exp(-np.arange(1, 21) * DT / tau)
    assert np.abs(np.array(torques) / decay - 1.0).max() < 1e-12
    for _ in range(100):
        m.advance_held()
    assert abs(m.output().motor_torque) < 1e-20            # exp(-50)
    # clear_fault while the flag is still set: cleared now, latched again at the next step
    assert m.clear_fault() == D.FAULT_INJECTED
    assert m.drive_status()['fault'] == D.FAULT_NONE
    m.advance_held()
    assert m.drive_status()['fault'] == D.FAULT_INJECTED
    # the flag off: the fault stays latched until clear_fault
    m.set_params(p)
    m.advance_held()
    assert m.drive_status()['fault'] == D.FAULT_INJECTED
    theta1 = m.output().motor_angle
    assert abs(theta1 - target) > 20.0                  # stopped far from the old target
    assert m.clear_fault() == D.FAULT_INJECTED
    held = []
    for _ in range(500):
        m.advance_held()
        held.append(m.output().motor_angle)
    st = m.drive_status()
    assert st['fault'] == D.FAULT_NONE and st['mode'] == D.MODE_POSITION
    # it holds where it stopped (the self-locking thread carries the load at zero torque,
    # so the hold moves by round-off only; resuming the old target would move 20+ rad)
    assert np.abs(np.array(held) - theta1).max() < 1e-6


# 5. Every fault clears -----------------------------------------------------------------------

@pytest.mark.parametrize('sensors', ['ideal', 'quantised'])
def test_frozen_sensors_hold_then_follow_the_truth_again(sensors):
    """fault.encoder_freeze / scale_freeze hold the readings (rate 0); off, they follow again."""
    q = dict(encoder_counts=COUNTS, scale_resolution=RES) if sensors == 'quantised' else {}
    p = horizontal(**q)
    hs = p.hand_sign
    m = LeadScrewModel(p, dt=DT)
    # torque mode (the drive does not use the readings): back and forth by some radians
    tq = 0.02 * np.sin(2 * math.pi * np.arange(200) * DT / 0.2)
    m.run(tq)
    m.set_params(p.replace(fault_encoder_freeze=True, fault_scale_freeze=True))
    a0, x0 = m.joint_values()[:2]
    r = m.run(tq)
    assert np.ptp(r['motor_angle']) > 1.0 and np.ptp(r['nut_position']) > 1e-4
    assert (r['sensor_screw_angle'] == a0).all() and (r['sensor_nut_position'] == x0).all()
    assert (r['sensor_screw_velocity'] == 0.0).all() and (r['sensor_nut_velocity'] == 0.0).all()
    m.set_params(p)
    r = m.run(tq)
    if sensors == 'ideal':   # the truth, bit for bit
        for s, t in (('sensor_screw_angle', 'screw_angle'),
                     ('sensor_nut_position', 'nut_position'),
                     ('sensor_screw_velocity', 'screw_velocity'),
                     ('sensor_nut_velocity', 'nut_velocity')):
            assert r[s].tobytes() == r[t].tobytes(), s
    else:   # the floor of the truth again (4 eps: the rounding before the floor)
        d_a = hs * (r['motor_angle'] - r['sensor_screw_angle'])
        d_x = r['nut_position'] - r['sensor_nut_position']
        tol_a = 4 * EPS * np.abs(r['motor_angle']).max()
        tol_x = 4 * EPS * np.abs(r['nut_position']).max()
        assert d_a.min() >= -tol_a and d_a.max() < COUNT + tol_a
        assert d_x.min() >= -tol_x and d_x.max() < RES + tol_x
        # from the second sample on, the velocity is the difference quotient again (2 eps of
        # |v| + |v_prev|: the unfiltered update, as in test_sensors)
        v = np.diff(r['sensor_screw_angle']) / DT
        prev = r['sensor_screw_velocity'][:-1]
        assert (np.abs(r['sensor_screw_velocity'][1:] - v)
                <= 2 * EPS * (np.abs(v) + np.abs(prev))).all()


def test_jam_off_lets_the_nut_pass_and_a_new_jam_blocks_the_side_the_nut_is_on():
    """fault.jam off: the nut moves past the jam position; on again beyond it, it blocks -x."""
    p = ScrewParams.from_dict({'fault': {'jam': True, 'jam_position': JAM}}, base=horizontal())
    m = LeadScrewModel(p, dt=DT)
    lo, hi = jam_bounds(p)
    up = rows(D.MODE_VELOCITY, 2000, velocity=nut_rate(m, 0.005))
    r = m.run(None, commands=up)
    assert JAM < r['nut_position'][-1] <= JAM + hi
    m.set_params(p.replace(fault_jam=False))
    r = m.run(None, commands=up[:1000])
    assert r['nut_position'][-1] > JAM + 4e-3              # 1 s at 5 mm/s, past the jam
    m.set_params(p)                                        # the nut now lies above it
    r = m.run(None, commands=rows(D.MODE_VELOCITY, 3000, velocity=nut_rate(m, -0.005)))
    pen = settled_against_the_jam(m, r)
    assert r['nut_position'][-1] < JAM and lo <= pen <= hi, (pen, lo, hi)


def test_torque_scale_back_to_one_gives_the_full_torque():
    """fault.motor_torque_scale back to 1: the motor delivers the command again."""
    p = vertical_screw()
    m = LeadScrewModel(p.replace(fault_motor_torque_scale=0.25), dt=DT)
    cmd = np.full(10, 0.08)              # any torque: only the motor's output is looked at
    r = m.run(cmd)
    assert np.abs(r['motor_torque'] - 0.02).max() <= 2 * EPS * 0.08
    m.set_params(p)
    r = m.run(cmd)
    # no lag: te + (T - te), one rounding of T
    assert np.abs(r['motor_torque'] - 0.08).max() <= 2 * EPS * 0.08


def test_drop_rates_back_to_zero_lose_nothing():
    """fault.command_drop_rate and state_drop_rate back to 0: every message gets through."""
    lossy = ScrewParams(fault_command_drop_rate=0.5, fault_state_drop_rate=0.5, sensor_seed=3)
    hold, line = CommandHold(params=lossy), StateDelivery(lossy)
    for i in range(200):
        hold.torque_command(0.1, i)
        line.sample(i, i, (0.0,))
    assert 0 < hold.dropped < 200 and 0 < line.dropped < 200
    clean = lossy.replace(fault_command_drop_rate=0.0, fault_state_drop_rate=0.0)
    hold.set_faults(clean)
    line.set_faults(clean)
    d_cmd, d_state = hold.dropped, line.dropped
    line.due(10 ** 6)
    for i in range(200, 2200):
        assert hold.torque_command(1e-3 * i, i) is None and hold.torque == 1e-3 * i
        line.sample(i, i, (float(i),))
        assert line.due(i) == [(i, (float(i),))]
    assert (hold.dropped, line.dropped) == (d_cmd, d_state)
    assert DROPPED not in [hold.torque_command(0.0, 0)]


# 6. Determinism ---------------------------------------------------------------------------------

def faulty_run(seed):
    """Run a noisy, jammed, weakened axis through a schedule of fault changes; return the runs."""
    p = ScrewParams.from_dict({
        'encoder_counts': COUNTS, 'encoder_noise': 1e-3, 'encoder_bias': 2e-3,
        'scale_resolution': RES, 'scale_noise': 2e-6, 'scale_bias': -1e-6,
        'velocity_filter_time': 2e-3, 'sensor_seed': seed, 'following_error_limit': 50.0,
        'fault': {'jam': True, 'jam_position': 0.004, 'motor_torque_scale': 0.8}},
        base=load_preset('tr12x3'))
    m = LeadScrewModel(p, dt=DT)
    # (changes, nut target from, to [m]) per block of 200 ticks
    schedule = [({}, 0.0, 0.006),                                   # into the jam
                ({'fault_scale_freeze': True}, 0.002, 0.002),       # back off, scale frozen
                ({'fault_scale_freeze': False, 'fault_encoder_freeze': True}, 0.002, 0.002),
                ({'fault_encoder_freeze': False, 'fault_drive_fault': True}, 0.002, 0.002),
                ({'fault_drive_fault': False, 'fault_jam': False}, 0.002, 0.008)]
    out = []
    for i, (change, x_from, x_to) in enumerate(schedule):
        p = p.replace(**change)
        m.set_params(p)
        if i == 4:
            m.clear_fault()
        n = 200 if i != 2 else 20          # a short freeze: the feedback-blind hold drifts
        theta = m.nut_to_motor(np.linspace(x_from, x_to, n))
        out.append(m.run(None, commands=rows(D.MODE_POSITION, n, position=theta,
                                             velocity=np.gradient(theta, DT))))
    return out, m.state.copy()


def test_same_parameters_commands_and_seeds_resimulate_bit_for_bit():
    """The same parameters, commands, fault changes and seeds give bit-identical runs."""
    a, sa = faulty_run(11)
    b, sb = faulty_run(11)
    for ra, rb in zip(a, b):
        assert sorted(ra) == sorted(rb)
        for key in ra:
            assert ra[key].tobytes() == rb[key].tobytes(), key
    assert sa.tobytes() == sb.tobytes()
    # the run exercised the faults: the jam held (static penetration < 0.1 mm), the
    # sensors froze, the injected fault latched, and without the jam the nut passed it
    assert 0.004 < a[0]['nut_position'].max() < 0.004 + 1e-4
    assert np.ptp(a[1]['sensor_nut_position']) == 0.0 and np.ptp(a[2]['sensor_screw_angle']) == 0.0
    assert (a[3]['fault'] == D.FAULT_INJECTED).all()
    assert (a[4]['fault'] == D.FAULT_NONE).all() and a[4]['nut_position'][-1] > 0.006
    # and the seed matters: another one gives other readings
    c, _ = faulty_run(12)
    assert np.count_nonzero(a[0]['sensor_screw_angle'] != c[0]['sensor_screw_angle']) > 100
