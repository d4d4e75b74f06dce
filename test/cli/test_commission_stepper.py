"""
``commission`` of a stepper without encoder (nema17_tr8x8): pull-out curve, load line, no counts.

The run has no breakaway (a stepper takes no torque); the nut is reported
from the commanded steps, so the twin is not judged, and lost steps are
said to be invisible without an encoder, never counted. The load line is
checked against the thread's closed form computed here.
"""
import json
import math

from helpers import cli_ok
from leadscrew_sim import load_preset
import pytest


@pytest.fixture(scope='module')
def stepper_report(tmp_path_factory):
    """Return the report dict of the commission of nema17_tr8x8's default run."""
    d = tmp_path_factory.mktemp('stepper')
    cli_ok('simulate', '--preset', 'nema17_tr8x8', '--excite', 'commission', '-q',
           '-o', d / 'run.mcap')
    cli_ok('commission', d / 'run.mcap', '-o', d / 'out', '-q')
    return json.loads((d / 'out' / 'report.json').read_text()), (d / 'out' / 'report.html')


def test_no_lost_step_count_without_an_encoder(stepper_report):
    report, page = stepper_report
    s = report['sections']
    assert list(s['axis']['segments']) == ['sweep', 'reversals', 'chirp']
    assert 'breakaway' not in [m['part'] for m in s['axis']['missing']]
    assert s['stepper']['lost_steps'] == 'lost steps cannot be seen without an encoder'
    assert 'lost steps cannot be seen without an encoder' in page.read_text()
    assert 'lost_full_steps' not in json.dumps(report)
    assert 'sentence' not in s['twin'] and s['twin']['parts'] == {}
    assert any('not measured' in c for c in s['twin']['cannot'])


def test_pull_out_curve_and_load_line(stepper_report):
    """
    The curve runs past max_step_rate to its knee; the load line is the closed form.

    Load at rate r: the thread torque raising m g, W r_m (mu' + tan l) / (1 -
    mu' tan l) with mu' the preset's law at the sliding speed, plus the total
    inertia (motor, screw, moving mass through the lead) times the step
    acceleration, within 1e-9.
    """
    report, _page = stepper_report
    st = report['sections']['stepper']
    p = load_preset('nema17_tr8x8')
    rates = [c['step_rate'] for c in st['curve']]
    assert rates[-1] > p.max_step_rate and st['max_step_rate'] == p.max_step_rate
    assert st['knee'] is not None and st['knee'] > p.max_step_rate
    lam, t = p.lead_angle, math.tan(p.lead_angle)
    for c in st['curve']:
        v = c['step_rate'] * p.step_angle * p.lead / (2 * math.pi)
        vs = v / math.sin(lam)
        mu = p.thread_factor * (p.mu_k + (p.mu_s - p.mu_k) * math.exp(
            -(vs / p.stribeck_velocity) ** p.stribeck_exponent) + p.mu_viscous * vs)
        w = p.moving_mass * p.gravity * math.sin(p.inclination) + p.guide_coulomb
        j = p.motor_inertia + p.screw_inertia + p.moving_mass * (p.lead / (2 * math.pi)) ** 2
        expect = w * p.r_m * (mu + t) / (1 - mu * t) + p.bearing_coulomb + \
            p.collar_mu * p.collar_radius * w + j * p.step_acceleration * p.step_angle
        assert c['load_torque'] == pytest.approx(expect, rel=1e-9)
    inside = [c for c in st['curve'] if c['step_rate'] <= p.max_step_rate]
    if st['loses_steps_at'] is None:
        assert all(c['pullout_torque'] > c['load_torque'] for c in inside)
        assert st['margin'] == pytest.approx(min(c['pullout_torque'] / c['load_torque']
                                                 for c in inside))
