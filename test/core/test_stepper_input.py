"""
The stepper's parameters, presets and bad input (interfaces.md, "Stepper drive (v3)").

Oracles: the allowed ranges of the issue (positive motor figures, microsteps a
power of two up to 256, a supply above run_current * phase_resistance), each
refused with one message naming the parameter, the value and what is allowed;
the datasheet figures of the presets' motors (their YAML comments); torque
commands refused by every entry point (model, command rules, simulate).
"""
import math
import subprocess
import sys

import numpy as np
import pytest

from leadscrew_sim import LeadScrewModel, load_preset
from leadscrew_sim.core.commands import CommandHold, NutMap, REJECTED
from leadscrew_sim.core.params import ParameterError, ScrewParams

STEPPER = dict(drive_type='stepper', linear_scale=False)

POSITIVE = ('step_angle', 'holding_torque', 'run_current', 'phase_resistance',
            'phase_inductance', 'supply_voltage', 'max_step_rate', 'step_acceleration')


def refused(match, **values):
    """Assert that a stepper set with ``values`` is refused; return the message."""
    with pytest.raises(ParameterError, match=match) as exc:
        ScrewParams.from_dict(dict(STEPPER, **values))
    return str(exc.value)


@pytest.mark.parametrize('name', POSITIVE)
@pytest.mark.parametrize('value', [0.0, -1.0])
def test_zero_or_negative_motor_figures_refused(name, value):
    """A zero or negative motor figure is refused naming the parameter, value and range."""
    msg = refused(f"parameter '{name}'", **{name: value})
    assert repr(value) in msg and 'outside the allowed range (0.0,' in msg, msg


@pytest.mark.parametrize('value', [0, 3, 12, 100, 512])
def test_microsteps_must_be_a_power_of_two_up_to_256(value):
    """Microsteps other than 1, 2, 4, ..., 256 are refused."""
    msg = refused("parameter 'microsteps'", microsteps=value)
    assert str(value) in msg
    assert 'power of two' in msg or '[1, 256]' in msg, msg


def test_every_power_of_two_microstep_setting_is_taken():
    """1 .. 256 in powers of two are valid."""
    for k in range(9):
        assert ScrewParams.from_dict(dict(STEPPER, microsteps=2 ** k)).microsteps == 2 ** k


def test_supply_below_the_winding_voltage_refused():
    """supply_voltage <= run_current * phase_resistance cannot drive the current: refused."""
    msg = refused("parameter 'supply_voltage'", supply_voltage=2.0, run_current=1.7,
                  phase_resistance=1.5)
    assert '2.0 V' in msg and 'above 2.55 V' in msg, msg
    ScrewParams.from_dict(dict(STEPPER, supply_voltage=2.6, run_current=1.7,
                               phase_resistance=1.5))


def test_inconsistent_stepper_sets_refused():
    """Hold above run current, detent at the holding torque, unknown type, scale feedback."""
    refused("parameter 'hold_current'", hold_current=2.0, run_current=1.7)
    refused("parameter 'detent_torque'", detent_torque=0.4, holding_torque=0.4)
    refused("parameter 'drive_feedback'", drive_feedback='linear_scale', linear_scale=True)
    with pytest.raises(ParameterError, match="parameter 'drive_type'"):
        ScrewParams.from_dict(dict(drive_type='hybrid'))
    # a servo set does not check the stepper figures against each other
    ScrewParams.from_dict(dict(hold_current=5.0, supply_voltage=1.0))


@pytest.mark.parametrize('name, figures', [
    ('nema17_tr8x8', dict(run_current=1.7, phase_resistance=1.5, phase_inductance=2.8e-3,
                          holding_torque=0.4, detent_torque=0.022, motor_inertia=5.4e-6)),
    ('nema23_tr12x3', dict(run_current=2.8, phase_resistance=0.9, phase_inductance=2.5e-3,
                           holding_torque=1.26, motor_inertia=3.0e-5)),
])
def test_presets_carry_their_datasheet_figures(name, figures):
    """The presets are steppers with their datasheet's figures, and plausible ones."""
    p = load_preset(name)
    assert p.drive_type == 'stepper' and p.microsteps == 16 and not p.linear_scale
    assert p.encoder_counts == 0
    assert p.step_angle == pytest.approx(math.radians(1.8))
    for key, value in figures.items():
        assert getattr(p, key) == pytest.approx(value), key
    assert 0.1 < p.torque_constant < 1.0                          # N m/A = V s/rad
    assert 0.5e-3 < p.phase_inductance / p.phase_resistance < 5e-3   # L / R [s]
    assert p.supply_voltage > 5 * p.run_current * p.phase_resistance
    assert p.hold_current < p.run_current and p.detent_torque < 0.1 * p.holding_torque
    assert p.inclination == pytest.approx(math.pi / 2)


def test_model_refuses_torque_commands():
    """A stepper model refuses torques: advance, run with torques, torque command rows."""
    p = load_preset('nema17_tr8x8')
    m = LeadScrewModel(p)
    state = m.state.copy()
    for call in (lambda: m.advance(0.1), lambda: m.step(0.0), lambda: m.run([0.1, 0.2]),
                 lambda: m.command('torque', effort=0.2),
                 lambda: m.run(None, commands=[[0, math.nan, math.nan, 0.3]])):
        with pytest.raises(ValueError, match='stepper'):
            call()
    assert np.array_equal(m.state, state)
    m.command('torque', effort=0.0)        # the hold it keeps after reset
    m.advance_held()


def test_command_rules_refuse_torque_commands():
    """The command rules (node and resim) reject torque_command and joint_commands efforts."""
    p = load_preset('nema17_tr8x8')
    hold = CommandHold('', 0.5, NutMap.of_model(LeadScrewModel(p)), params=p)
    assert 'stepper' in hold.torque_command(0.1, 0)
    result, reason = hold.joint_commands(['screw_joint'], [], [], [0.1], 0)
    assert result == REJECTED and 'stepper' in reason
    assert hold.take_series('torque_command', [0.1, 0.2], [0, 1]) is None
    assert hold.velocity_command(0.01, 0) is None
    assert hold.joint_commands(['nut_joint'], [0.01], [], [], 1)[0] != REJECTED
    assert hold.command_at(1)[0] == 2    # position


def test_simulate_refuses_a_torque_input_for_a_stepper(tmp_path):
    """``simulate --torque`` on a stepper preset: one error line and a non-zero exit."""
    out = tmp_path / 'x.mcap'
    res = subprocess.run([sys.executable, '-m', 'leadscrew_sim.cli', 'simulate', '--preset',
                          'nema17_tr8x8', '--torque', '0.1', '--duration', '0.1', '-q', '-o',
                          str(out)], capture_output=True, text=True, timeout=300)
    assert res.returncode != 0, res.stderr
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1 and 'torque' in lines[0] and 'stepper' in lines[0], res.stderr
    assert not out.exists()


def test_velocity_beyond_the_max_step_rate_is_clipped():
    """A velocity command above max_step_rate steps at max_step_rate."""
    p = load_preset('nema17_tr8x8')
    m = LeadScrewModel(p)
    w_max = p.max_step_rate * p.step_angle
    r = m.run(None, commands=np.tile([1, math.nan, -5.0 * w_max, math.nan], (500, 1)))
    assert np.min(r['step_rate']) == pytest.approx(-w_max, rel=1e-12)
    assert r['lost_full_steps'][-1] == 0
