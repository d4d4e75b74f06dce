"""
The command rules shared by the node and resim: modes, NaN padding, merging, nut mapping, timeouts.

The expected values follow from the rules as interfaces.md states them (a
finite position makes a position command, else a finite velocity a velocity
command, else an effort a torque command; NaN is "not commanded") and the
rigid kinematics theta = theta0 + h (2 pi / l) (x - x0), computed here by hand.
"""
import math

import pytest

from leadscrew_sim.core.commands import (ACCEPTED, CommandHold, IGNORED, NutMap, REJECTED)
from leadscrew_sim.core.drive_modes import (MODE_POSITION, MODE_QUICKSTOP, MODE_TORQUE,
                                            MODE_VELOCITY)

NAN = float('nan')
MS = 1_000_000
LEAD = 0.003
K = -2 * math.pi / LEAD          # right hand: h = -1


def hold(timeout=0.0):
    return CommandHold('ax_', timeout, NutMap(theta0=1.5, x0=0.01, k=K))


def same(a, b):
    return all((x == y) or (x != x and y != y) for x, y in zip(a, b))


def test_position_only_for_the_nut_joint_is_a_position_command_through_the_lead():
    h = hold()
    assert h.joint_commands(['ax_nut_joint'], [0.013], [], [], 0) == (ACCEPTED, None)
    mode, theta, w, t = h.command_at(0)
    assert mode == MODE_POSITION
    assert theta == pytest.approx(1.5 + K * 0.003, rel=1e-15)
    assert w != w and t == 0.0


def test_velocity_and_effort_of_the_nut_map_through_the_lead():
    h = hold()
    h.joint_commands(['ax_nut_joint'], [], [0.002], [50.0], 0)
    mode, theta, w, t = h.command_at(0)
    assert mode == MODE_VELOCITY and theta != theta
    assert w == pytest.approx(K * 0.002, rel=1e-15)
    assert t == pytest.approx(50.0 / K, rel=1e-15)      # T theta' = F v


def test_nan_padding_means_not_commanded():
    h = hold()
    names = ['other_joint', 'ax_screw_joint']
    assert h.joint_commands(names, [NAN, NAN], [NAN, 3.0], [NAN, NAN], 0)[0] == ACCEPTED
    assert same(h.command_at(0), (MODE_VELOCITY, NAN, 3.0, 0.0))
    assert h.joint_commands(names, [NAN, NAN], [NAN, NAN], [1.0, 0.25], MS)[0] == ACCEPTED
    assert same(h.command_at(MS), (MODE_TORQUE, NAN, NAN, 0.25))


def test_separate_messages_of_one_tick_merge_into_one_command():
    h = hold()
    h.joint_commands(['ax_screw_joint'], [2.0], [], [], 5 * MS)
    h.joint_commands(['ax_screw_joint'], [], [0.5], [], 5 * MS)     # same tick: feed-forward
    assert same(h.command_at(5 * MS), (MODE_POSITION, 2.0, 0.5, 0.0))
    h.joint_commands(['ax_screw_joint'], [], [0.7], [], 6 * MS)     # next tick: a new command
    assert same(h.command_at(6 * MS), (MODE_VELOCITY, NAN, 0.7, 0.0))


@pytest.mark.parametrize('names,pos,vel,eff,why', [
    (['ax_screw_joint', 'b'], [1.0], [], [], '1 positions for 2 names'),
    (['ax_screw_joint', 'ax_screw_joint'], [], [], [1.0, 1.0], 'naming'),
    (['ax_screw_joint', 'ax_nut_joint'], [1.0, 0.1], [], [], 'both'),
    (['ax_screw_joint'], [NAN], [NAN], [NAN], 'nothing'),
    (['ax_screw_joint'], [], [math.inf], [], 'non-finite'),
    (['ax_screw_joint'], [], [], [], 'nothing'),
])
def test_malformed_joint_commands_are_rejected_with_a_reason(names, pos, vel, eff, why):
    h = hold()
    h.torque_command(0.1, 0)
    result, reason = h.joint_commands(names, pos, vel, eff, MS)
    assert result == REJECTED and why in reason
    assert same(h.command_at(MS), (MODE_TORQUE, NAN, NAN, 0.1))      # nothing changed


def test_a_message_without_our_joints_is_ignored():
    assert hold().joint_commands(['x_screw_joint'], [1.0], [], [], 0)[0] == IGNORED


def test_float64_commands_set_their_modes():
    h = hold()
    assert h.velocity_command(0.004, 0) is None
    assert same(h.command_at(0), (MODE_VELOCITY, NAN, K * 0.004, 0.0))
    assert h.position_command(0.02, MS) is None
    assert h.command_at(MS)[:2] == (MODE_POSITION, pytest.approx(1.5 + K * 0.01, rel=1e-15))
    assert 'non-finite' in h.velocity_command(NAN, 2 * MS)
    assert 'non-finite' in h.position_command(math.inf, 2 * MS)


def test_timeouts_per_mode():
    t_out = 0.5e9
    h = hold(timeout=0.5)
    h.torque_command(0.3, 0)
    assert h.command_at(int(t_out)) == (MODE_TORQUE, pytest.approx(NAN, nan_ok=True),
                                        pytest.approx(NAN, nan_ok=True), 0.3)
    assert h.command_at(int(t_out) + 1)[3] == 0.0 and h.stale
    h.velocity_command(0.001, 0)
    assert not h.stale
    assert h.command_at(int(t_out) + 1)[0] == MODE_QUICKSTOP and h.stale
    h.position_command(0.0, 0)
    assert h.command_at(10 ** 12)[0] == MODE_POSITION and not h.stale


def test_changed_command_hands_over_each_change_once():
    h = hold(timeout=0.5)
    assert h.changed_command(0) is not None         # the initial zero torque
    assert h.changed_command(MS) is None
    h.velocity_command(0.001, 2 * MS)
    assert h.changed_command(2 * MS)[0] == MODE_VELOCITY
    assert h.changed_command(3 * MS) is None
    late = 2 * MS + 10 ** 9
    assert h.changed_command(late)[0] == MODE_QUICKSTOP       # the timeout, once
    assert h.changed_command(late + MS) is None
    h.reset()
    assert h.changed_command(late + 2 * MS)[0] == MODE_TORQUE


def test_external_force_range():
    h = hold()
    assert h.external_force(100.0) is None and h.force == 100.0
    assert 'outside' in h.external_force(1e308)
    assert 'outside' in h.external_force(NAN)
    assert h.force == 100.0


def test_a_fixed_joint_command_mode_takes_feed_forwards_from_any_later_message():
    h = CommandHold('ax_', 0.0, NutMap(theta0=1.5, x0=0.01, k=K), 'position')
    assert h.joint_commands(['ax_screw_joint'], [], [0.5], [], 0)[0] == REJECTED   # no target
    h.joint_commands(['ax_screw_joint'], [2.0], [], [], MS)
    h.joint_commands(['ax_screw_joint'], [], [0.5], [], 3 * MS)    # another tick: still ff
    assert same(h.command_at(3 * MS), (MODE_POSITION, 2.0, 0.5, 0.0))
    auto = hold()
    auto.joint_commands(['ax_screw_joint'], [2.0], [], [], MS)
    auto.joint_commands(['ax_screw_joint'], [], [0.5], [], 3 * MS)   # auto: a velocity command
    assert same(auto.command_at(3 * MS), (MODE_VELOCITY, NAN, 0.5, 0.0))
