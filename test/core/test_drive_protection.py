"""
The drive's protections against a runaway and a far position command (doc/model.md section 16).

Oracles:
- the overspeed threshold is 1.2 times the rated speed, which config/tr12x3.yaml
  declares as max_screw_velocity: 300 rad/s (the test reads that file with
  yaml, not through the package): the fault latches at the end of the first
  step whose motor rate exceeds it, and the motor torque is off from then on;
- the end stop: without the limit the same torque runs the nut into it;
- a far position target is approached on a trapezoid of the reference rate
  v = min(velocity_limit, max_screw_velocity) and acceleration a =
  quick_stop_deceleration: the move of D takes D / v + v / a (closed form),
  and the nut's speed stays at the rated speed's nut speed v l / (2 pi) but
  for the loop's overshoot;
- a target within max_command_jump is taken at once: the run is bit for bit
  the run without the limit.
"""
import math
from pathlib import Path

import numpy as np
import pytest
import yaml

from leadscrew_sim import LeadScrewModel, load_preset
from leadscrew_sim.core.engine import drive as D

#: The preset's rated speed [rad/s], read from its file, and its overspeed trip.
RATED = float(yaml.safe_load(
    (Path(__file__).resolve().parents[2] / 'config' / 'tr12x3.yaml').read_text())
    ['/**']['ros__parameters']['max_screw_velocity'])
TRIP = 1.2 * RATED


def preset(**changes):
    """Return tr12x3 (vertical, 10 kg, self-locking) with ``changes``."""
    return load_preset('tr12x3', **changes)


def position_rows(n, theta):
    """Return n position-mode command rows to motor angle theta [rad]."""
    rows = np.full((n, 4), math.nan)
    rows[:, 0] = D.MODE_POSITION
    rows[:, 1] = theta
    return rows


def test_overspeed_trips_in_torque_mode_before_the_nut_reaches_the_end_stop():
    """A torque that runs the axis away latches overspeed at 1.2 x the rated speed; torque off."""
    p = preset()
    assert p.max_screw_velocity == pytest.approx(RATED, rel=1e-12)
    m = LeadScrewModel(p, dt=1e-3)
    r = m.run(np.full(3000, 1.0), drive_values=True)     # lowers the nut toward -x
    w = np.abs(r['motor_velocity'])
    k = int(np.argmax(w > TRIP))
    assert w[k] > TRIP and (w[:k] <= TRIP).all()
    assert m.drive_fault() == D.FAULT_OVERSPEED
    assert D.FAULT_NAMES[m.drive_fault()] == 'overspeed'
    # the fault acts from the next step on: the motor torque is off (the lag: none here)
    assert (r['motor_torque'][k + 1:] == 0.0).all()
    # the torque off, the self-locking thread stops the axis within a few mm of the trip,
    # and never reaches the end stop: it stays 0.1 m above stroke_min
    assert r['nut_position'].min() > p.stroke_min + 0.1
    assert abs(r['nut_velocity'][-1]) < 1e-6
    m.clear_fault()
    assert m.drive_fault() == D.FAULT_NONE


def test_without_the_limit_the_same_torque_crashes_into_the_end_stop():
    """max_screw_velocity 0 (no limit): the nut runs into the stop, no fault."""
    p = preset(max_screw_velocity=0.0)
    m = LeadScrewModel(p, dt=1e-3)
    r = m.run(np.full(4000, 1.0), drive_values=True)
    assert m.drive_fault() == D.FAULT_NONE
    assert np.abs(r['motor_velocity']).max() > 2 * TRIP
    assert r['nut_position'].min() < p.stroke_min + 1e-4


@pytest.mark.parametrize('mode', ['position', 'velocity'])
def test_the_loops_keep_below_the_trip(mode):
    """A 100 mm position step and a velocity command at the rated speed trip nothing."""
    p = preset()
    m = LeadScrewModel(p, dt=1e-3)
    if mode == 'position':
        m.command(D.MODE_POSITION, position=m.nut_to_motor(-0.1))
    else:
        m.command(D.MODE_VELOCITY, velocity=-RATED)
    w = []
    for _ in range(1500):
        m.advance_held()
        w.append(abs(m.output().motor_velocity))
    assert m.drive_fault() == D.FAULT_NONE
    # the reference is clipped to the rated speed; the loop overshoots it by < 20 %
    assert max(w) <= TRIP
    assert max(w) >= 0.99 * RATED


def test_a_far_position_command_is_approached_at_the_drives_limits():
    """Beyond max_command_jump the nut moves on the trapezoid D / v + v / a, at the rated speed."""
    x0, x1 = 0.1, 0.0
    p = preset(initial_position=x0, max_command_jump=1e-3)
    v = min(p.velocity_limit, RATED)                        # rad/s of the motor
    a = p.quick_stop_deceleration                           # rad/s^2
    lead = p.pitch * p.starts
    m = LeadScrewModel(p, dt=1e-3)
    d_rad = abs(x1 - x0) * 2.0 * math.pi / lead
    t_move = d_rad / v + v / a                              # the trapezoid's duration [s]
    r = m.run(None, commands=position_rows(int(1.5 * t_move * 1000) + 500,
                                           m.nut_to_motor(x1)))
    x, t = r['nut_position'], r['time']
    v_nut = v * lead / (2.0 * math.pi)
    # the loop follows the reference with its rate as feed-forward: a few % overshoot
    assert np.abs(r['nut_velocity']).max() <= 1.05 * v_nut
    assert m.drive_fault() == D.FAULT_NONE
    arrive = t[np.argmax(np.abs(x - x1) < 10e-6)]
    # within 5 % of the trapezoid (the loop's lag behind it is ~ 1 / K_p = 16 ms)
    assert arrive == pytest.approx(t_move, rel=0.05), (arrive, t_move)
    assert abs(x[-1] - x1) < 10e-6


def test_a_command_within_the_jump_is_taken_at_once():
    """A 0.5 mm step with max_command_jump 1 mm is the run without the limit, bit for bit."""
    runs = []
    for jump in (0.0, 1e-3):
        p = preset(max_command_jump=jump)
        m = LeadScrewModel(p, dt=1e-3)
        r = m.run(None, commands=position_rows(400, m.nut_to_motor(-5e-4)))
        runs.append(r['nut_position'])
        assert m.reference_gap() == 0.0
    assert np.array_equal(runs[0], runs[1])


def test_the_reference_gap_shows_the_approach():
    """reference_gap is the target less the reference while the approach lasts, then 0."""
    p = preset(initial_position=0.02, max_command_jump=1e-3)
    m = LeadScrewModel(p, dt=1e-3)
    target = m.nut_to_motor(0.0)
    m.command(D.MODE_POSITION, position=target)
    m.advance_held()
    gap = m.reference_gap()
    # after one step the reference moved a * dt^2 at most from the motor angle
    start = m.nut_to_motor(0.02)
    assert abs(gap - (target - start)) <= p.quick_stop_deceleration * 1e-6 + 1e-9
    for _ in range(2000):
        m.advance_held()
    assert m.reference_gap() == 0.0
