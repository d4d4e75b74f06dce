"""
The servo drive (doc/model.md section 16) against closed forms and independent recursions.

Oracles:
- the cascaded loop on a rigid, frictionless, backlash-free axis is linear: its
  response is that of the drive's difference equations (P position loop,
  PI velocity loop with conditional integration, torque held for the drive
  period T_d) on one body of inertia J_total, integrated with the kernel's
  substep rule (symplectic Euler, step h). :func:`cascade` simulates them in
  plain Python; it knows nothing of the kernel's contact or friction model.
  The continuous closed form (scipy) shows where the sample-and-hold matters;
- the steady state of the proportional loop under a constant load,
  e = T_load / (K_v K_p), and its zero with the integral;
- the backlash b of the thread: the limit cycle of a scale-fed loop and the
  approach-side offset +-b/2 of an encoder-fed one;
- the kinematics x = rt q for the limit switches, the quick stop ramp and
  the nut-motor mapping.
"""
import math
import os
import subprocess
import sys

import numpy as np
import pytest
from scipy import signal

from leadscrew_sim import LeadScrewModel, load_preset
from leadscrew_sim.analysis import linear
from leadscrew_sim.core.engine import drive as D
from leadscrew_sim.core.engine import layout as L


def cascade(j, h, m, n_sub, q_ref, kv, ti, kp, tmax=math.inf, vmax=math.inf, aw=True,
            t_load=0.0, every=1, velocity=None):
    """
    Run the drive's difference equations on a rigid body of inertia j [kg m^2] (q sense).

    The drive updates every m substeps of h [s] (T_d = m h): w_ref = clip(K_p
    (q_ref - q) + 0, +-vmax) (or the given velocity command), e = w_ref - w,
    T_u = K_v (e + I / T_i), T = clip(T_u, +-tmax), I += e T_d unless saturated
    (aw: conditional integration; aw=False integrates always). Each substep:
    w += h (T + t_load) / j, q += h w. Returns (q, w) every ``every`` substeps
    and the largest |I|.
    """
    q = w = integ = t = 0.0
    i_max = 0.0
    qs, ws = [], []
    td = m * h
    for k in range(n_sub):
        if k % m == 0:
            w_ref = velocity if velocity is not None else kp * (q_ref - q)
            w_ref = min(max(w_ref, -vmax), vmax)
            e = w_ref - w
            if ti > 0.0:
                t_u = kv * (e + integ / ti)
                if not aw or abs(t_u) < tmax or e * t_u < 0.0:
                    integ += e * td
            else:
                t_u = kv * e
            t = min(max(t_u, -tmax), tmax)
            i_max = max(i_max, abs(integ))
        w += h * (t + t_load) / j
        q += h * w
        if (k + 1) % every == 0:
            qs.append(q)
            ws.append(w)
    return np.array(qs), np.array(ws), i_max


def step_figures(t, y, final):
    """Return (overshoot [-], 2 % settling time [s]) of a step response y(t) toward final."""
    y = np.asarray(y) / final
    outside = np.nonzero(np.abs(y - 1.0) > 0.02)[0]
    return max(0.0, y.max() - 1.0), t[outside[-1] + 1]


def rigid_axis(**changes):
    """Tr12x3 made rigid and linear: no friction, no backlash, horizontal, stiff contact."""
    p = load_preset('tr12x3').replace(
        mu_s=0.0, mu_k=0.0, backlash=0.0, bearing_viscous=0.0, guide_viscous=0.0,
        inclination=0.0, contact_stiffness=1e10, contact_damping=2e4)
    return p.replace(**changes)


def position_rows(n, theta, velocity=math.nan, effort=math.nan):
    """Return n position-mode command rows (theta sense)."""
    c = np.empty((n, 4))
    c[:, 0] = D.MODE_POSITION
    c[:, 1] = theta
    c[:, 2] = velocity
    c[:, 3] = effort
    return c


def velocity_rows(n, omega, effort=math.nan):
    """Return n velocity-mode command rows (theta sense)."""
    c = np.empty((n, 4))
    c[:, 0] = D.MODE_VELOCITY
    c[:, 1] = math.nan
    c[:, 2] = omega
    c[:, 3] = effort
    return c


def run_held(m, n):
    """Run n held steps; return time [s], motor angle [rad], drive torque [N m], I [rad]."""
    rows = np.empty((n, 4))
    for k in range(n):
        m.advance_held()
        rows[k] = (m.time, m.output().motor_angle, m.drive_status()['drive_torque'],
                   m.state[L.S_DINT])
    return rows.T


# Linear step response -------------------------------------------------------------

@pytest.mark.parametrize('gains', ['preset', 'fast'])
def test_small_step_follows_the_discrete_closed_loop(gains):
    p = rigid_axis()
    j = linear.total_inertia(p)
    if gains == 'fast':   # w_v = 1000 rad/s, K_p = w_v / 2: an overshoot, w_v T_d = 0.25
        p = p.replace(velocity_gain=1000.0 * j, velocity_integral_time=4e-3, position_gain=500.0)
    kv, ti, kp = p.velocity_gain, p.velocity_integral_time, p.position_gain
    dt = 1e-4
    m = LeadScrewModel(p, dt=dt)
    md = D.update_period(m.nsub, dt, p.drive_rate)
    h = dt / m.nsub
    n = 1500 if gains == 'fast' else 3000
    theta0, step = m.output().motor_angle, 0.05
    r = m.run(None, commands=position_rows(n, theta0 + step))
    t = r['time']
    y_kernel = r['motor_angle'] - theta0
    hs = p.hand_sign
    q, _, _ = cascade(j, h, md, n * m.nsub, hs * step, kv, ti, kp, every=m.nsub)
    y_oracle = hs * q
    ov_k, ts_k = step_figures(t, y_kernel, step)
    ov_o, ts_o = step_figures(t, y_oracle, step)
    assert abs(ov_k - ov_o) <= 0.02 * ov_o + 1e-4, (ov_k, ov_o)
    assert abs(ts_k - ts_o) <= 0.02 * ts_o, (ts_k, ts_o)
    assert np.abs(y_kernel - y_oracle).max() < 1e-3 * step
    # the linear design figures of the doc table (exact zero-order hold at T_d) agree
    lr = linear.loop_response(p, dt=dt, nsub=m.nsub)
    assert lr['overshoot'] == pytest.approx(ov_k, abs=0.02 * ov_k + 1e-4)
    assert lr['settling_time'] == pytest.approx(ts_k, rel=0.03)
    if gains == 'fast':
        # at these gains the sample-and-hold matters: the continuous loop overshoots less
        cont = signal.TransferFunction([kv * kp * ti, kv * kp],
                                       [j * ti, kv * ti, kv * (1.0 + ti * kp), kv * kp])
        _, y_cont = signal.step(cont, T=t)
        ov_c, _ = step_figures(t, y_cont, 1.0)
        assert 0.05 < ov_o < 0.12 and ov_c < 0.9 * ov_o, (ov_o, ov_c)
    else:   # the shipped design rule: no overshoot, 2 % settling in about 21 / w_v
        assert ov_k < 1e-3 and ts_k == pytest.approx(21.2 / (kv / j), rel=0.05)


# Constant load and the integral -------------------------------------------------------

@pytest.mark.parametrize('feedback', ['motor_encoder', 'linear_scale'])
def test_constant_load_steady_state_error_vanishes_at_the_feedback(feedback):
    # Vertical, frictionless: gravity is a constant load torque m g rt on the motor.
    p = load_preset('tr12x3').replace(mu_s=0.0, mu_k=0.0, drive_feedback=feedback)
    rt = p.r_m * math.tan(p.lead_angle)
    t_load = (p.nut_mass + p.payload_mass) * p.gravity * rt
    e_p = t_load / (p.velocity_gain * p.position_gain)      # P-only steady-state error [rad]
    errors = {}
    for ti in (0.0, p.velocity_integral_time):
        m = LeadScrewModel(p.replace(velocity_integral_time=ti), dt=1e-3)
        theta0, x0 = m.output().motor_angle, m.output().nut_position
        r = m.run(None, commands=position_rows(2000, theta0))
        if feedback == 'motor_encoder':
            err = r['motor_angle'][-1] - theta0
        else:   # the scale reads the nut: its error in motor radians
            err = m.nut_to_motor(r['nut_position'][-1]) - m.nut_to_motor(x0)
        errors[ti] = abs(err)
    # proportional loop: the closed form (the load sags the axis by T_load / (K_v K_p))
    assert errors[0.0] == pytest.approx(e_p, rel=1e-3)
    # with the integral the error decays with the slowest closed-loop pole (about
    # 0.16 w_v = 50 rad/s: e^-100 after 2 s); 1e-6 of e_p leaves room for round-off
    assert errors[p.velocity_integral_time] < 1e-6 * e_p


# Backlash in the loop -----------------------------------------------------------------

def backlash_axis(feedback):
    """Tr12x3 horizontal with a guide friction that holds the nut while the screw turns."""
    return load_preset('tr12x3').replace(inclination=0.0, guide_coulomb=20.0, backlash=1e-4,
                                         drive_feedback=feedback)


def test_scale_feedback_with_the_integral_hunts_across_the_backlash():
    p = backlash_axis('linear_scale')
    m = LeadScrewModel(p, dt=1e-3)
    target = 1e-3
    r = m.run(None, commands=position_rows(20000, m.nut_to_motor(target)))
    tail = slice(5000, None)
    motor = m.motor_to_nut(r['motor_angle'][tail]) - target    # motor in nut terms [m]
    nut = r['nut_position'][tail] - target
    b = p.backlash
    # a limit cycle: the motor swings through the whole gap (and a little into the
    # flanks) again and again, the nut is pushed past the target both ways
    assert b <= np.ptp(motor) <= 1.2 * b, np.ptp(motor)
    assert np.ptp(nut) < 0.1 * b
    crossings = np.count_nonzero(np.diff(np.sign(nut)) != 0)
    assert crossings >= 4, crossings
    # motor-side swings with a period: count the passes through the middle of the gap
    mid = np.count_nonzero(np.diff(np.sign(motor)) != 0)
    assert mid >= 6, mid


def test_encoder_feedback_settles_with_the_nut_off_by_half_the_backlash():
    p = backlash_axis('motor_encoder')
    b = p.backlash
    compliance = p.guide_coulomb / p.contact_stiffness   # flank deflection under the guide force
    errs = []
    for target in (1e-3, -1e-3):    # approach from below, then from above
        m = LeadScrewModel(p, dt=1e-3)
        goal = m.nut_to_motor(target)
        r = m.run(None, commands=position_rows(3000, goal))
        tail = slice(2000, None)
        assert np.ptp(r['motor_angle'][tail]) < 1e-9                  # settled
        assert abs(r['motor_angle'][-1] - goal) < 1e-9
        errs.append(r['nut_position'][-1] - target)
    # the nut trails the flank that pushed it: -b/2 from below, +b/2 from above (it
    # coasts a little off the flank as the guide friction stops it: 0.4 um here)
    assert errs[0] < 0.0 < errs[1]
    for e in errs:
        assert 0.95 * 0.5 * b <= abs(e) <= 0.5 * b + compliance, errs


# Velocity mode on the stick-slip preset ---------------------------------------------

def test_velocity_mode_stick_slips_slow_and_slides_steadily_fast():
    p = load_preset('stick_slip')
    results = {}
    for v_nut in (2e-4, 2e-2):      # raising the 20 kg load at 0.2 and 20 mm/s
        m = LeadScrewModel(p, dt=1e-3)
        omega = m.nut_to_motor(v_nut) - m.nut_to_motor(0.0)     # motor rate [rad/s]
        r = m.run(None, commands=velocity_rows(4000, omega))
        tail = slice(2000, None)
        x, t = r['nut_position'], r['time']
        mean_v = (x[-1] - x[2000]) / (t[-1] - t[2000])
        results[v_nut] = (mean_v, r['stuck'][tail].mean(), r['nut_velocity'][tail])
    mean_v, stuck, v = results[2e-4]
    assert stuck > 0.5                      # stick phases most of the time ...
    assert v.max() > 10 * 2e-4              # ... and slips far faster than commanded
    assert v.min() < 0.1 * 2e-4
    mean_v, stuck, v = results[2e-2]
    assert stuck == 0.0 and np.ptp(v) < 1e-3 * 2e-2     # steady sliding
    assert mean_v == pytest.approx(2e-2, rel=5e-3)


# Saturation and anti-windup ------------------------------------------------------------

def test_saturated_step_anti_windup_bounds_the_overshoot():
    p = rigid_axis(max_torque=0.1)
    j = linear.total_inertia(p)
    kv, ti, kp = p.velocity_gain, p.velocity_integral_time, p.position_gain
    dt = 1e-3
    m = LeadScrewModel(p, dt=dt)
    md = D.update_period(m.nsub, dt, p.drive_rate)
    h = dt / m.nsub
    n = 1500
    theta0, step = m.output().motor_angle, 20.0     # rad: 9.5 mm of nut travel
    m.command(D.MODE_POSITION, position=theta0 + step)
    t, angle, torque, ints = run_held(m, n)
    y_kernel = angle - theta0
    assert np.abs(torque).max() == pytest.approx(p.max_torque)   # saturated
    hs = p.hand_sign
    lim = dict(tmax=p.max_torque, vmax=p.velocity_limit, every=m.nsub)
    q_aw, _, i_aw = cascade(j, h, md, n * m.nsub, hs * step, kv, ti, kp, **lim)
    q_wu, _, i_wu = cascade(j, h, md, n * m.nsub, hs * step, kv, ti, kp, aw=False, **lim)
    ov_k, ts_k = step_figures(t, y_kernel, step)
    ov_aw, ts_aw = step_figures(t, hs * q_aw, step)
    ov_wu = (hs * q_wu / step).max() - 1.0
    assert abs(ov_k - ov_aw) <= 0.02 * ov_aw + 1e-3, (ov_k, ov_aw)
    assert abs(ts_k - ts_aw) <= 0.02 * ts_aw, (ts_k, ts_aw)
    # with anti-windup the overshoot is what the torque-limited deceleration gives (23 %
    # here); without it the integral winds up during the saturated acceleration and the
    # loop overshoots by several times the step (and does not settle)
    assert ov_k < 0.3 and ov_wu > 3.0, (ov_k, ov_wu)
    # no blow-up: the integral stays at what the unsaturated phases put in, four orders
    # of magnitude below the wound-up one
    i_k = np.abs(ints).max()
    assert i_k <= 1.01 * i_aw and i_aw < 1e-3 * i_wu, (i_k, i_aw, i_wu)


# Faults ----------------------------------------------------------------------------------

def test_blocked_axis_latches_following_error_and_only_clear_fault_releases_it():
    # Horizontal tr12x3 with an end stop at 10 mm; the target ramps to 30 mm at 20 mm/s.
    p = load_preset('tr12x3').replace(inclination=0.0, stroke_max=0.01,
                                      following_error_limit=2 * math.pi)
    m = LeadScrewModel(p, dt=1e-3)
    n = 1500
    xs = np.minimum(np.arange(1, n + 1) * 1e-3 * 0.02, 0.03)
    theta = m.nut_to_motor(xs)
    v_ff = np.gradient(theta, 1e-3)
    c = position_rows(n, theta, velocity=v_ff)
    r = m.run(None, commands=c)
    k = int(np.argmax(r['fault'] != 0))
    assert r['fault'][k] == D.FAULT_FOLLOWING_ERROR and (r['fault'][k:] != 0).all()
    assert r['nut_position'][k] == pytest.approx(0.01, abs=2e-4)   # against the stop
    assert (r['nut_position'][:k] < 0.0102).all()
    assert r['motor_torque'][k + 1:].tolist() == [0.0] * (n - k - 1)    # torque off
    assert m.drive_status()['fault_name'] == 'following_error'
    # new commands do not clear it
    r = m.run(None, commands=position_rows(50, m.nut_to_motor(0.0)))
    assert (r['fault'] == D.FAULT_FOLLOWING_ERROR).all() and (r['motor_torque'] == 0.0).all()
    m.command('velocity', velocity=-5.0)
    m.advance_held()
    assert m.drive_status()['fault'] == D.FAULT_FOLLOWING_ERROR
    # clear_fault: position mode holding where the axis is, without a jump
    theta_now = m.output().motor_angle
    assert m.clear_fault() == D.FAULT_FOLLOWING_ERROR
    assert m.drive_status()['mode_name'] == 'position'
    for _ in range(200):
        m.advance_held()
    st = m.drive_status()
    assert st['fault'] == D.FAULT_NONE and st['mode'] == D.MODE_POSITION
    assert abs(m.output().motor_angle - theta_now) < 0.05
    assert m.clear_fault() == D.FAULT_NONE


def test_torque_limit_fault_and_injected_fault():
    p = load_preset('tr12x3').replace(inclination=0.0, stroke_max=0.002,
                                      torque_limit_time=0.1)
    m = LeadScrewModel(p, dt=1e-3)
    omega = m.nut_to_motor(0.02) - m.nut_to_motor(0.0)     # 20 mm/s into the stop
    r = m.run(None, commands=velocity_rows(1000, omega))
    k = int(np.argmax(r['fault'] != 0))
    assert r['fault'][k] == D.FAULT_TORQUE_LIMIT
    hit = int(np.argmax(np.abs(r['drive_torque']) >= p.max_torque))
    assert 0.1 <= r['time'][k] - r['time'][hit] <= 0.1 + 2e-3     # after torque_limit_time
    assert (r['motor_torque'][k + 1:] == 0.0).all()
    m.clear_fault()
    m.inject_fault()
    m.advance_held()
    assert m.drive_status()['fault_name'] == 'injected' and m.output().motor_torque == 0.0
    m.advance(0.3)                                   # torque mode is off too
    assert m.output().motor_torque == 0.0


# Limit and home switches -----------------------------------------------------------------

def test_tripped_min_switch_stops_motion_toward_min_and_allows_backing_off():
    # horizontal, with a guide friction that stops the nut when the screw stops (without
    # it the nut coasts on inside the backlash)
    p = load_preset('tr12x3').replace(inclination=0.0, guide_coulomb=20.0,
                                      limit_min_position=-0.005, switch_hysteresis=5e-4,
                                      home_position=-0.002)
    m = LeadScrewModel(p, dt=1e-3)
    assert m.drive_status()['home']                  # x = 0 >= home_position
    down = m.nut_to_motor(-0.01) - m.nut_to_motor(0.0)      # -10 mm/s [rad/s]
    r = m.run(None, commands=velocity_rows(1500, down))
    k = int(np.argmax(r['limit_min']))
    assert r['nut_position'][k] <= -0.005 < r['nut_position'][k - 1]
    assert not r['home'][k]
    x_stop = r['nut_position'][-1]
    # braking from 10 mm/s at the loop's rate: well within a millimetre
    assert -0.0055 < x_stop <= -0.005
    assert np.abs(r['nut_velocity'][-200:]).max() < 1e-6
    # still refused toward -x: velocity, position and torque mode
    r = m.run(None, commands=velocity_rows(300, 2 * down))
    assert abs(r['nut_position'][-1] - x_stop) < 2e-5
    r = m.run(None, commands=position_rows(300, m.nut_to_motor(-0.02)))
    assert abs(r['nut_position'][-1] - x_stop) < 2e-5
    toward_min = -p.hand_sign * 0.5                 # theta-sense torque moving the nut to -x
    x1 = m.output().nut_position
    m.advance(toward_min)
    for _ in range(100):
        m.advance(toward_min)
    assert m.output().motor_torque == 0.0 and abs(m.output().nut_position - x1) < 1e-6
    # backing off toward +x is allowed; the switch releases past the hysteresis
    r = m.run(None, commands=velocity_rows(1000, -down))
    assert r['nut_position'][-1] > x_stop + 0.009
    rel = int(np.argmax(~r['limit_min']))
    assert r['nut_position'][rel] > -0.005 + 5e-4 >= r['nut_position'][rel - 1]


# Quick stop ----------------------------------------------------------------------------------

def test_stale_velocity_quick_stop_then_hold_on_a_back_drivable_vertical_axis():
    p = load_preset('tr8x8')
    assert not p.self_locking
    m = LeadScrewModel(p, dt=1e-3)
    omega = m.nut_to_motor(0.01) - m.nut_to_motor(0.0)      # raise at 10 mm/s
    m.command('velocity', velocity=omega)
    for _ in range(500):
        m.advance_held()
    assert m.output().motor_velocity == pytest.approx(omega, rel=1e-3)
    m.command('quick_stop')                  # what the command intake does on a timeout
    w0 = m.output().motor_velocity
    m.advance_held()
    k = 1
    while m.drive_status()['mode'] == D.MODE_QUICKSTOP:
        m.advance_held()
        m.command(D.MODE_QUICKSTOP)          # repeating it does not restart the ramp
        k += 1
        assert k < 1000
    t_ramp = k * 1e-3
    assert t_ramp == pytest.approx(abs(w0) / p.quick_stop_deceleration, abs=2e-3)
    assert m.drive_status()['mode_name'] == 'position'
    x_stop = m.output().nut_position
    xs = []
    for _ in range(5000):
        m.advance_held()
        xs.append(m.output().nut_position)
    # the hold (integral against gravity, stiction in the thread) hunts by a few um
    assert np.abs(np.array(xs) - x_stop).max() < 10e-6


# Torque mode, API and determinism ------------------------------------------------------------

def test_torque_mode_commands_take_the_torque_path_bit_for_bit():
    p = load_preset('anti_backlash')
    tq = 0.3 * np.sin(np.arange(300) * 0.05)
    a = LeadScrewModel(p).run(tq)
    c = np.zeros((300, 4))
    c[:, 0], c[:, 1:3], c[:, 3] = D.MODE_TORQUE, math.nan, tq
    b = LeadScrewModel(p).run(None, commands=c)
    for key in a:
        assert a[key].tobytes() == b[key].tobytes(), key
    m1, m2 = LeadScrewModel(p), LeadScrewModel(p)
    for x in tq[:50]:
        m1.advance(float(x))
        m2.command('torque', effort=float(x))
        m2.advance_held()
    assert m1.state.tobytes() == m2.state.tobytes()


def test_command_api_validation_and_mapping():
    p = load_preset('tr12x3')
    m = LeadScrewModel(p)
    with pytest.raises(ValueError):
        m.command('jog')
    with pytest.raises(ValueError):
        m.command(D.MODE_POSITION)              # no position
    with pytest.raises(ValueError):
        m.command(D.MODE_VELOCITY, velocity=math.inf)
    with pytest.raises(ValueError):
        m.run(np.zeros(2), commands=np.zeros((2, 4)))
    with pytest.raises(ValueError):
        m.run(None, commands=np.full((2, 4), 7.0))
    # the mapping: the initial state maps to itself; one lead of travel is one turn
    o = m.output()
    assert m.nut_to_motor(o.nut_position) == pytest.approx(o.motor_angle, abs=1e-12)
    assert m.nut_to_motor(o.nut_position + p.lead) - o.motor_angle == pytest.approx(
        p.hand_sign * 2 * math.pi, rel=1e-12)
    assert m.motor_to_nut(m.nut_to_motor(0.0123)) == pytest.approx(0.0123, abs=1e-15)
    st = m.drive_status()
    assert st['mode_name'] == 'torque' and st['fault_name'] == 'none'
    assert st['effective_drive_rate'] == pytest.approx(m.nsub / (5 * m.dt))   # 18 substeps, m 5
    assert D.effective_rate(18, 1e-3, 4000.0) == 3600.0


def test_position_mode_with_feed_forward_tracks_the_motion():
    # A 20 mm/s ramp with velocity feed-forward: the following error stays small.
    p = load_preset('tr12x3')
    m = LeadScrewModel(p, dt=1e-3)
    n = 1000
    xs = np.arange(1, n + 1) * 1e-3 * 0.02
    theta = m.nut_to_motor(xs)
    r = m.run(None, commands=position_rows(n, theta, velocity=np.gradient(theta, 1e-3)))
    assert (r['mode'] == D.MODE_POSITION).all()
    fe = np.abs(r['following_error'][500:])
    assert fe.max() < 0.05                                   # rad, under 25 um of nut
    assert r['nut_position'][-1] == pytest.approx(xs[-1], abs=1.5e-4)   # backlash + lag


SCRIPT = r'''
import hashlib, math, sys
import numpy as np
from leadscrew_sim import LeadScrewModel, load_preset
from leadscrew_sim.analysis import linear
n = int(sys.argv[1])
h = hashlib.sha256()
for name in ('tr8x8', 'stick_slip'):
    p = load_preset(name).replace(drive_feedback='linear_scale', following_error_limit=50.0)
    m = LeadScrewModel(p, dt=1e-3)
    theta0 = m.output().motor_angle
    c = np.zeros((n, 4))
    c[:, 0] = np.where(np.arange(n) < n // 2, 2, 1)
    c[:, 1] = theta0 + 5.0 * np.sin(np.arange(n) * 0.02)
    c[:, 2] = 3.0
    c[:, 3] = 0.0
    res = m.run(None, commands=c)
    for key in sorted(res):
        h.update(np.ascontiguousarray(res[key]).tobytes())
    m.command('quick_stop')
    for _ in range(20):
        m.advance_held()
    h.update(m.state.tobytes())
print(h.hexdigest())
'''


@pytest.mark.slow
def test_drive_fresh_compile_cached_load_and_plain_python_agree(tmp_path):
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path / 'numba_cache'))

    def run(e):
        out = subprocess.run([sys.executable, '-c', SCRIPT, '200'], env=e,
                             capture_output=True, text=True, timeout=900)
        assert out.returncode == 0, out.stderr[-2000:]
        return out.stdout.strip()
    compiled = run(env)
    cached = run(env)
    plain = run(dict(env, NUMBA_DISABLE_JIT='1'))
    assert compiled == cached == plain
