"""
The linear frequency response against oracles written here (doc/frequency_response.md).

- the two-inertia resonance and anti-resonance of a compliant coupling, in closed form;
- the drive's velocity and position loop bandwidths that doc/model.md reports,
  checked against a python-control model of the sampled cascade built here;
- gain and phase margins against control.margin on the test's own loop.
"""
import dataclasses
import math
from pathlib import Path
import re

import control
import numpy as np
import pytest

from leadscrew_sim.analysis.freqresp.measure import linear_response
from leadscrew_sim.analysis.freqresp.summary import bandwidth, margins, resonances
from leadscrew_sim.core.params import ParameterError, ScrewParams
from leadscrew_sim.core.presets import load_preset

DOC = Path(__file__).resolve().parents[2] / 'doc' / 'model.md'


def lead_ratio(p):
    """r_t = l / 2 pi [m/rad] from the pitch and the starts."""
    return p.pitch * p.starts / (2.0 * math.pi)


def two_inertia_axis(**kw):
    """Return a frictionless horizontal axis with a compliant coupling and a stiff contact."""
    base = dict(mu_s=0.0, mu_k=0.0, backlash=0.0, inclination=0.0, coupling_stiffness=20.0,
                coupling_damping=0.0, contact_stiffness=1e11, contact_damping=0.0,
                bearing_viscous=0.0, guide_viscous=0.0, payload_mass=2.0)
    base.update(kw)
    return ScrewParams(**base)


def test_two_inertia_resonance_and_antiresonance():
    p = two_inertia_axis()
    jl = p.screw_inertia + (p.nut_mass + p.payload_mass) * lead_ratio(p) ** 2
    jm, kc = p.motor_inertia, p.coupling_stiffness
    f_res = math.sqrt(kc * (jm + jl) / (jm * jl)) / (2.0 * math.pi)
    f_anti = math.sqrt(kc / jl) / (2.0 * math.pi)
    r = linear_response(p, 'torque', 'motor_velocity', frequency=np.geomspace(1.0, 5e3, 50))
    res, anti = resonances(r)
    # 0.5 %: the brief's bound; the contact (1e11 N/m) shifts the modes by ~1e-5
    assert res and anti
    assert res[0][0] == pytest.approx(f_res, rel=5e-3)
    assert anti[0][0] == pytest.approx(f_anti, rel=5e-3)
    # and the response itself peaks there: |H| at f_res far above its neighbours
    h = linear_response(p, 'torque', 'motor_velocity', frequency=[0.7 * f_res, f_res * 1.0001])
    assert abs(h.response[1]) > 100.0 * abs(h.response[0])


def model_md_row(preset):
    """Return the gains table row of doc/model.md for a preset as a list of cells."""
    for line in DOC.read_text().splitlines():
        if line.startswith(f'| `{preset}` |'):
            return [c.strip() for c in line.strip('|').split('|')]
    raise AssertionError(f'{preset} not in the gains table of {DOC}')


def control_cascade(j, kv, ti, kp, td, f):
    """Return (w/w_ref, q/q_ref) at f [Hz] of the sampled cascade on J s^2, by python-control."""
    plant = control.c2d(control.ss([[0.0, 1.0], [0.0, 0.0]], [[0.0], [1.0 / j]],
                                   [[1.0, 0.0], [0.0, 1.0]], 0.0), td, 'zoh')
    z = control.tf([1.0, 0.0], [1.0], td)
    pi = kv + (kv / ti) * td / (z - 1.0)
    zz = np.exp(2j * math.pi * f * td)
    g_q = control.ss2tf(plant[0, 0])(zz)          # torque -> q
    g_w = control.ss2tf(plant[1, 0])(zz)          # torque -> w
    c = pi(zz)
    vel = c * g_w / (1.0 + c * g_w)
    # position mode: T = PI (K_p (q_ref - q) - w), q = G_q T, w = G_w T
    pos = c * kp * g_q / (1.0 + c * kp * g_q + c * g_w)
    return vel, pos


def bw(f, h):
    """Return the -3 dB bandwidth [Hz] against the lowest frequency's gain, on f's grid."""
    below = np.nonzero(np.abs(h) < abs(h[0]) / math.sqrt(2.0))[0]
    return f[below[0]]


def test_drive_loop_bandwidths_equal_model_md():
    row = model_md_row('tr12x3')
    j, kv, ti, kp = (float(row[i]) for i in (1, 2, 3, 4))
    rate, f_vel, f_pos = float(row[6]), float(row[7]), float(row[8])
    fo = np.geomspace(0.01, rate / 2.0, 40000)
    vel, pos = control_cascade(j, kv, ti, kp, 1.0 / rate, fo)
    # the oracle reproduces the doc's figures (the doc rounds to 2-3 digits)
    assert bw(fo, vel) == pytest.approx(f_vel, rel=0.02)
    assert bw(fo, pos) == pytest.approx(f_pos, rel=0.02)
    p = load_preset('tr12x3', mu_s=0.0, mu_k=0.0)     # the doc's frictionless axis
    f = np.geomspace(1.0, 400.0, 1500)
    for inp, out, ref in (('velocity_command', 'motor_velocity', f_vel),
                          ('position_command', 'motor_angle', f_pos)):
        r = linear_response(p, inp, out, frequency=f, sampling='drive')
        # 2 %: the brief's bound (the contact compliance and rounding are within it)
        assert bandwidth(r) == pytest.approx(ref, rel=0.02), inp


def test_margins_agree_with_control_margin():
    p = two_inertia_axis(coupling_stiffness=0.0, contact_stiffness=1e11, payload_mass=1.0,
                         velocity_gain=0.02, velocity_integral_time=0.005, drive_rate=2000.0,
                         torque_lag=2e-4)
    td = 1.0 / 2000.0
    r = linear_response(p, loop='velocity', quantity='L', sampling='drive',
                        frequency=np.geomspace(1.0, 0.4999 / td, 20000))
    assert r.loop_gain is not None
    m = margins(r.frequency, r.loop_gain)
    j = p.motor_inertia + p.screw_inertia + (p.nut_mass + p.payload_mass) * lead_ratio(p) ** 2
    plant = control.c2d(control.tf([1.0], [j * p.torque_lag, j, 0.0]), td, 'zoh')
    z = control.tf([1.0, 0.0], [1.0], td)
    loop = (p.velocity_gain + p.velocity_gain / p.velocity_integral_time * td / (z - 1.0)) * plant
    gms, pms, _, wpcs, wgcs, _ = control.stability_margins(loop, returnall=True)
    # the double integrator puts the phase at -180 deg as w -> 0 (control reports a
    # crossover there); the margin that limits the gain is the one above the crossover
    wcp = float(wgcs[0])
    pm = float(pms[0])
    gm = min(g for g, w in zip(gms, wpcs) if w > wcp)
    assert 1.5 < gm < 100.0                      # a real phase crossover below Nyquist
    # 1 %: the brief's bound (grid of 20000 points, log-interpolated crossings)
    assert 10.0 ** (m['gain_margin_db'] / 20.0) == pytest.approx(gm, rel=0.01)
    assert m['phase_margin_deg'] == pytest.approx(pm, rel=0.01)
    assert m['crossover'] == pytest.approx(wcp / (2.0 * math.pi), rel=0.01)
    s = linear_response(p, loop='velocity', quantity='S', sampling='drive',
                        frequency=r.frequency)
    assert np.max(np.abs(s.response)) == pytest.approx(m['ms'], rel=1e-9)


def test_discretised_response_is_the_zoh_of_the_continuous():
    # a frictionless free axis in torque mode: motor rate / torque = 1 / (J s), exactly
    p = two_inertia_axis(coupling_stiffness=0.0, contact_stiffness=1e11)
    j = p.motor_inertia + p.screw_inertia + (p.nut_mass + p.payload_mass) * lead_ratio(p) ** 2
    f = np.array([1.0, 30.0, 150.0])
    dt = 1e-3
    step = linear_response(p, 'torque', 'motor_velocity', frequency=f, sampling='step', dt=dt)
    z = np.exp(2j * math.pi * f * dt)
    # held over the step ending at the stamp: w_k = w_(k-1) + T_k dt / J -> H = dt / (J (1 - 1/z))
    expect = p.hand_sign ** 2 * dt / (j * (1.0 - 1.0 / z))
    # 2e-3: the contact mode (~35 kHz) the oracle leaves out bends the response by 6e-4 at 150 Hz
    np.testing.assert_allclose(step.response, expect, rtol=2e-3)
    cont = linear_response(p, 'torque', 'motor_velocity', frequency=f)
    # the hold's shift at 150 Hz and 1 kHz: +27 deg (doc/frequency_response.md, "step")
    shift = np.degrees(np.angle(step.response[2] / cont.response[2]))
    assert shift == pytest.approx(27.0, abs=0.1)


def test_unknown_names_are_refused():
    p = load_preset('tr12x3')
    with pytest.raises(ParameterError, match="'input'"):
        linear_response(p, 'speed', 'motor_velocity', frequency=[1.0])
    with pytest.raises(ParameterError, match="'output'"):
        linear_response(p, 'torque', 'nut_angle', frequency=[1.0])
    with pytest.raises(ParameterError, match="'quantity'"):
        linear_response(p, loop='velocity', quantity='M', frequency=[1.0])
    with pytest.raises(ParameterError, match='following_error'):
        linear_response(p, 'velocity_command', 'following_error', frequency=[1.0])


def test_stuck_thread_at_rest_locks_the_screw():
    # tr12x3 at rest is self-locking: a small torque only strains the stuck thread's
    # contact, so the nut moves against the rigid kinematics' sense, by -r_m cot(lambda) q
    p = dataclasses.replace(load_preset('tr12x3'), torque_lag=0.0)
    f = [0.5]
    q = linear_response(p, 'torque', 'motor_angle', frequency=f)
    x = linear_response(p, 'torque', 'nut_position', frequency=f)
    rm = (p.major_diameter - p.pitch / 2.0) / 2.0
    lam = math.atan(p.pitch * p.starts / (2.0 * math.pi * rm))
    ratio = x.response[0] / (p.hand_sign * q.response[0])
    assert ratio.real == pytest.approx(-rm / math.tan(lam), rel=1e-6)
    # locked: the rotor turns by the stiff thread contact only (k r_m^2 / (sin cos)^2)
    k_eq = p.contact_stiffness * rm ** 2 / (math.sin(lam) * math.cos(lam)) ** 2
    assert abs(q.response[0]) == pytest.approx(1.0 / k_eq, rel=0.05)
    with pytest.raises(ParameterError, match='backlash'):
        linear_response(dataclasses.replace(p, inclination=0.0), 'torque', 'motor_angle',
                        frequency=f)


def test_model_md_has_the_numbers_this_test_reads():
    row = model_md_row('tr12x3')
    assert all(re.match(r'^[0-9.e+-]+$', row[i]) for i in (1, 2, 3, 4, 6, 7, 8))


def test_sliding_linearisation_is_the_stability_analysis_one():
    # the continuous velocity loop while sliding has the eigenvalues the stability
    # analysis finds for the same operating point (its translation mode aside)
    from leadscrew_sim.analysis.freqresp.linear import closed_loop
    from leadscrew_sim.analysis.stability.linearise import eigenvalues
    from leadscrew_sim.analysis.stability.operating_point import operating_point
    for preset, speed in (('tr12x3', 0.01), ('tr12x3', -0.004), ('stick_slip', 1e-3)):
        p = dataclasses.replace(load_preset(preset), velocity_filter_time=0.0)
        ours = closed_loop(p, 'velocity_command', 'motor_velocity', speed).system().poles()
        ours = ours[np.abs(ours) > 1e-9 * np.abs(ours).max()]
        theirs = eigenvalues(operating_point(p, speed, 'velocity'), p)
        np.testing.assert_allclose(np.sort_complex(ours), np.sort_complex(theirs),
                                   rtol=1e-7, atol=1e-9 * np.abs(theirs).max())


@pytest.mark.parametrize('coupling', [0.0, 40.0])
def test_split_nut_sliding_zeros_are_the_ideal_drive_modes(coupling):
    # torque -> motor angle: its zeros are the modes with the motor held still, which is
    # the stability analysis's ideal drive (q_m prescribed); both halves of the split nut
    # and the preload spring are in those modes (4 states rigid, 6 with the coupling)
    from leadscrew_sim.analysis.freqresp.linear import closed_loop
    from leadscrew_sim.analysis.stability.linearise import eigenvalues
    from leadscrew_sim.analysis.stability.operating_point import operating_point
    p = load_preset('anti_backlash', coupling_stiffness=coupling)
    assert p.anti_backlash
    for speed in (0.01, -0.004):
        zeros = closed_loop(p, 'torque', 'motor_angle', speed).system().zeros()
        modes = eigenvalues(operating_point(p, speed, 'ideal'), p)
        assert len(zeros) == len(modes) == (4 if coupling == 0.0 else 6)
        # 1e-7: the generalised eigenvalue problem of the zeros against a plain eigvals
        # (both ~1e-10 relative here); a missing half-nut or spring moves them by > 1 %
        for m in modes:                          # each mode has its zero (pairs matched)
            assert np.min(np.abs(zeros - m)) <= 1e-7 * abs(m), (m, zeros)


def test_split_nut_stuck_at_rest_has_both_contacts():
    # at rest both halves are held by stiction: each moves by -r_m cot(lambda) q, its
    # contact deflected by -(r_m / (sin cos)) q; the potential 2 k (r_m / (sin cos))^2 q^2 / 2
    # makes the rotor's static compliance 1 / (2 k_eq) (the preload spring is not strained)
    p = load_preset('anti_backlash', torque_lag=0.0)
    assert p.anti_backlash and p.mu_s > 0.0 and p.coupling_stiffness == 0.0
    rm = (p.major_diameter - p.pitch / 2.0) / 2.0
    lam = math.atan(p.pitch * p.starts / (2.0 * math.pi * rm))
    k_eq = p.contact_stiffness * rm ** 2 / (math.sin(lam) * math.cos(lam)) ** 2
    q = linear_response(p, 'torque', 'motor_angle', frequency=[0.5])
    # 1e-3: the inertia (J + m r_m^2 cot^2) w^2 at 0.5 Hz is ~1e-8 of 2 k_eq; the contact
    # damping's phase at 0.5 Hz is ~1e-4
    assert abs(q.response[0]) == pytest.approx(1.0 / (2.0 * k_eq), rel=1e-3)
    x = linear_response(p, 'torque', 'nut_position', frequency=[0.5])
    ratio = x.response[0] / (p.hand_sign * q.response[0])
    assert ratio.real == pytest.approx(-rm / math.tan(lam), rel=1e-6)
    # free (friction out): the thread turns the screw, the halves ride on their flanks;
    # at 0.5 Hz the velocity loop follows its command (|T| within 1 % of 1)
    free = linear_response(p, 'velocity_command', 'nut_velocity', frequency=[0.5], rest='free')
    assert abs(free.response[0]) == pytest.approx(1.0, rel=0.01)
