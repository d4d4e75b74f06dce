"""
The derived figures against the closed forms of the thread and against runs of the model.

The profiles of core/excitation run through the model (torque mode tick by
tick with the breakaway controller, velocity and position profiles through
the drive, their commands passed through CommandHold as the node does), and
the sweep once through ``simulate``, its recording read with mcap_ros2; the
oracles are the quasi-static relations of doc/model.md section 7, written
out here from the geometry (lead angle, flank angle, thread factor), and for
the reversal error a synthetic run whose deviations are known.
"""
import math

from leadscrew_sim import LeadScrewModel, load_preset
from leadscrew_sim.analysis import figures as F
from leadscrew_sim.core.commands import CommandHold, NutMap
from leadscrew_sim.analysis.excitation.profiles import make_profile
from leadscrew_sim.core.params import ScrewParams
import numpy as np
import pytest

DT = 1e-3


def run_profile(params, profile):
    """Run ``profile`` on the model; return the arrays figures takes (state times)."""
    m = LeadScrewModel(params, dt=DT)
    n = int(round(profile.duration / DT))
    t_cmd = np.arange(n) * DT
    if profile.kind == 'torque':
        fn = profile.torque_source()
        cmd, rows = [], []
        x = m.output().nut_position
        for k in range(n):
            cmd.append(fn(k, t_cmd[k], x, None))
            m.advance(cmd[-1])
            o = m.output()
            x = o.nut_position
            rows.append((o.motor_torque, o.motor_velocity, o.nut_position, o.nut_velocity))
        r = dict(zip(('motor_torque', 'motor_velocity', 'nut_position', 'nut_velocity'),
                     np.array(rows).T))
        c = np.array(cmd)
    else:
        hold = CommandHold('', 0.0, NutMap.of_model(m), params=params)
        c = profile.values(t_cmd)
        commands = np.empty((n, 4))
        for k in range(n):
            if profile.kind == 'velocity':
                hold.velocity_command(c[k], k)
            else:
                hold.position_command(c[k], k)
            commands[k] = hold.command_at(k)
        r = m.run(None, None, commands=commands)
    # The command logged at t acts on [t, t + dt): the state at t + dt carries it.
    return dict(time=t_cmd + DT, command=c, **{k: np.asarray(r[k]) for k in (
        'motor_torque', 'motor_velocity', 'nut_position', 'nut_velocity')})


class Thread:
    """The closed forms of doc/model.md sections 2 and 7, from the raw parameters."""

    def __init__(self, p):
        d_m = p.major_diameter - p.pitch / 2.0
        self.tan = p.pitch * p.starts / (math.pi * d_m)
        self.lam = math.atan(self.tan)
        psi_a = math.radians({'trapezoidal': 15.0, 'acme': 14.5, 'square': 0.0}[p.thread_form])
        self.factor = 1.0 / math.cos(math.atan(math.tan(psi_a) * math.cos(self.lam)))
        self.r = d_m / 2.0
        self.p = p
        self.load = (p.nut_mass + p.payload_mass) * p.gravity * math.sin(p.inclination)

    def mu(self, v_nut):
        """Apparent coefficient at a nut speed: sliding speed v / sin(lambda) on the flank."""
        p = self.p
        v = abs(v_nut) / math.sin(self.lam)
        return self.factor * (p.mu_k + (p.mu_s - p.mu_k) * math.exp(
            -(v / p.stribeck_velocity) ** p.stribeck_exponent) + p.mu_viscous * v)

    def raise_(self, mu):
        """Torque to drive against the load: W r (mu' + tan) / (1 - mu' tan)."""
        return self.load * self.r * (mu + self.tan) / (1.0 - mu * self.tan)

    def lower(self, mu):
        """Torque to drive with the load: W r (mu' - tan) / (1 + mu' tan); < 0 back-drives."""
        return self.load * self.r * (mu - self.tan) / (1.0 + mu * self.tan)

    def eta(self, mu):
        """Forward efficiency tan (1 - mu' tan) / (tan + mu')."""
        return self.tan * (1.0 - mu * self.tan) / (self.tan + mu)

    def eta_back(self, mu):
        """Back-driving efficiency (tan - mu') / (tan (1 + mu' tan))."""
        return (self.tan - mu) / (self.tan * (1.0 + mu * self.tan))


@pytest.mark.parametrize('preset, sets', [
    ('tr12x3', dict(backlash=0.0)),                                         # self-locking
    ('tr12x3', dict(backlash=0.0, bearing_coulomb=0.01, collar_mu=0.1, collar_radius=0.006)),
    ('tr8x8', dict(backlash=0.0)),                                          # back-drives
])
def test_breakaway_torques_are_the_static_closed_form(preset, sets):
    p = ScrewParams.from_dict(sets, base=load_preset(preset))
    th = Thread(p)
    rest = p.bearing_coulomb + p.collar_mu * p.collar_radius * th.load
    mu_s = p.mu_s * th.factor
    # Right-hand thread, vertical: +theta lowers (the load helps), -theta raises.
    up, down = th.lower(mu_s) + rest, -(th.raise_(mu_s) + rest)
    prof = make_profile('breakaway', p, ramp_time=1.0, dwell=0.3)
    rate = prof.options['peak'] / prof.options['ramp_time']
    run = run_profile(p, prof)
    b = F.breakaway_torques(run['time'], run['command'], run['motor_torque'],
                            run['nut_position'])
    # The onset shows once the nut moved delta = 1 um; after the slip the torque
    # excess grows as rate t on the axis' inertia J (motor, screw, nut through
    # the lead), so the screw turns rate t^3 / (6 J) and the nut moves delta by
    # t_d = (6 J delta / (rate l / 2 pi))^(1/3) (13 ms for both presets), the
    # Stribeck drop only shortening it; 1.5 t_d leaves room for the share of
    # the excess the thread friction takes as the nut accelerates.
    lead = p.pitch * p.starts / (2 * math.pi)
    inertia = p.motor_inertia + p.screw_inertia + (p.nut_mass + p.payload_mass) * lead ** 2
    t_d = (6 * inertia * 1e-6 / (rate * lead)) ** (1 / 3)
    for s, closed in ((1, up), (-1, down)):
        got = b[s]
        assert got is not None and got.center == prof.options['center']
        # True stiction: no slip before the closed-form torque (round-off aside).
        assert s * (got.torque - closed) >= -1e-9 * abs(closed)
        assert s * (got.torque - closed) <= rate * 1.5 * t_d, (s, got.torque, closed, t_d)


def test_no_breakaway_below_the_static_band():
    p = ScrewParams.from_dict(dict(backlash=0.0), base=load_preset('tr12x3'))
    th = Thread(p)
    peak = 0.5 * th.lower(p.mu_s * th.factor)          # half the smaller edge of the band
    run = run_profile(p, make_profile('breakaway', p, center=0.0, peak=peak, ramp_time=0.5,
                                      dwell=0.1))
    assert F.derived_figures('breakaway', run)['breakaway'] == {1: None, -1: None}


@pytest.mark.parametrize('preset', ['tr12x3', 'tr8x8'])
def test_stribeck_points_and_efficiencies_are_the_closed_forms(preset):
    # No viscous losses: the steady torque is the thread's alone.
    p = ScrewParams.from_dict(dict(bearing_viscous=0.0, guide_viscous=0.0),
                              base=load_preset(preset))
    th = Thread(p)
    prof = make_profile('sweep', p, levels=6)
    run = run_profile(p, prof)
    fig = F.derived_figures('sweep', run, load=F.axial_load(p))
    points = fig['stribeck']
    assert sorted(pt.command for pt in points) == sorted(
        s * v for s in (1, -1) for v in prof.speeds(prof.options))
    rows, best = fig['efficiency']
    eta = {id(pt): (kind, e) for pt, kind, e in rows}
    checked = 0
    for pt in points:
        if abs(pt.command) / math.sin(th.lam) < 10 * p.stribeck_velocity:
            continue                   # below: the Stribeck rise and stick-slip, next test
        mu = th.mu(pt.command)
        # +x raises: -theta torque W r (...) for a right-hand thread; -x lowers.
        closed = -th.raise_(mu) if pt.command > 0 else th.lower(mu)
        # The velocity loop settles within 0.3 s to e^-15 of its step (real pole
        # -0.158 omega_v, omega_v = 314 rad/s); 1e-5 is far above that and far below
        # the 1e-2 that mu_k against mu_s would change.
        assert pt.torque == pytest.approx(closed, rel=1e-5), (pt.command, pt.torque, closed)
        assert pt.speed == pytest.approx(pt.command, rel=1e-5)
        kind, e = eta[id(pt)]
        assert kind == ('forward' if pt.command > 0 else 'backdrive')
        assert e == pytest.approx(th.eta(mu) if kind == 'forward' else th.eta_back(mu),
                                  rel=1e-5)
        checked += 1
    assert checked >= 6
    mu_fast = th.mu(prof.options['v_max'])
    assert best['forward'] == pytest.approx(th.eta(mu_fast), rel=1e-5)
    assert best['backdrive'] == pytest.approx(th.eta_back(mu_fast), rel=1e-5)
    # tr12x3 self-locks in motion too (mu'_k > tan lambda): back-driving efficiency < 0.
    assert (best['backdrive'] < 0) == (p.mu_k * th.factor > th.tan)


def test_slow_levels_lie_between_the_kinetic_and_the_static_torque():
    # Sliding at a quarter of the Stribeck velocity: the friction rises toward
    # mu_s, and the drive sticks and slips. The mean torque of the level is above
    # the kinetic closed form and cannot exceed the static one (a stuck thread
    # holds below breakaway, a slipping one carries less).
    p = ScrewParams.from_dict(dict(bearing_viscous=0.0, guide_viscous=0.0),
                              base=load_preset('tr12x3'))
    th = Thread(p)
    prof = make_profile('sweep', p, levels=3, measure=2.0)
    points = F.derived_figures('sweep', run_profile(p, prof))['stribeck']
    slow = [pt for pt in points if abs(pt.command) == prof.options['v_min']]
    assert len(slow) == 2
    mu_k, mu_s = p.mu_k * th.factor, p.mu_s * th.factor
    for pt in slow:
        kinetic, static = (th.raise_(mu_k), th.raise_(mu_s)) if pt.command > 0 else (
            th.lower(mu_k), th.lower(mu_s))
        assert kinetic < abs(pt.torque) <= static, (pt.command, pt.torque, kinetic, static)


def test_reversal_error_of_a_synthetic_run_is_its_known_offset():
    # The nut reads e_up below the target after an approach from below, e_down
    # above it after one from above, plus white noise sigma: B_i = -(e_up + e_down).
    p = load_preset('tr12x3')
    prof = make_profile('iso230', p, targets=4, cycles=3, travel=0.01, dwell=0.5, speed=0.01)
    t = np.arange(int(prof.duration / DT)) * DT
    c = prof.values(t)
    d = np.diff(c, prepend=c[0])
    last = np.zeros_like(c)                       # sign of the last move of the command
    sign = 0.0
    for i, step in enumerate(d):
        sign = np.sign(step) if step != 0 else sign
        last[i] = sign
    e_up, e_down, sigma = 12e-6, 7e-6, 1e-6
    x = c - np.where(last > 0, e_up, 0.0) + np.where(last < 0, e_down, 0.0) + \
        np.random.default_rng(3).normal(0.0, sigma, len(c))
    r = F.reversal_error(t, c, x, window=0.2)
    assert r.targets == pytest.approx(prof.target_positions(), abs=1e-15)
    assert r.approaches == ((3, 3),) * 4
    # Each mean: 200 samples x 3 cycles; the difference of two: sigma sqrt(2 / 600);
    # 5 of those is a bound the noise passes with probability 1 - 6e-7.
    tol = 5 * sigma * math.sqrt(2 / 600)
    assert r.reversal == pytest.approx([-(e_up + e_down)] * 4, abs=tol)
    assert r.mean_up == pytest.approx([-e_up] * 4, abs=tol)
    assert r.mean_down == pytest.approx([e_down] * 4, abs=tol)
    assert r.max_reversal == pytest.approx(e_up + e_down, abs=tol)


@pytest.mark.parametrize('name, feedback', [('iso230', 'motor_encoder'),
                                            ('iso230', 'linear_scale'),
                                            ('reversals', 'motor_encoder')])
def test_reversal_error_of_a_horizontal_axis_is_its_backlash(name, feedback):
    # Horizontal, guide friction 20 N: the drive closes on the motor encoder,
    # so the nut lags a target by half the backlash on either side (plus the
    # flank deflection F/k = 0.2 um, less what it coasts into the gap after the
    # screw stops): B = -b within [-b - 2 F/k, -0.95 b]. With the linear scale
    # the loop closes on the nut and the backlash vanishes from B (below 5 % b).
    p = ScrewParams.from_dict(dict(inclination=0.0, guide_coulomb=20.0,
                                   drive_feedback=feedback), base=load_preset('tr12x3'))
    options = dict(targets=3, cycles=2, travel=0.01) if name == 'iso230' else dict(cycles=2)
    prof = make_profile(name, p, dwell=1.0, **options)
    r = F.derived_figures(name, run_profile(p, prof))['reversal']
    assert len(r.targets) == (3 if name == 'iso230' else 1)
    b, deflection = p.backlash, p.guide_coulomb / p.contact_stiffness
    if feedback == 'motor_encoder':
        assert all(-b - 2 * deflection <= x <= -0.95 * b for x in r.reversal), r
    else:
        assert r.max_reversal < 0.05 * b, r


def test_hold_series_and_undefined_efficiency():
    got = F.hold_series([1.0, 2.0, 4.0], [10.0, 20.0, 40.0], [0.5, 1.0, 1.5, 3.9, 4.0, 9.0])
    assert np.array_equal(got[1:], [10.0, 10.0, 20.0, 40.0, 40.0]) and math.isnan(got[0])
    pt = F.StribeckPoint(0.01, 0.01, 0.1, 0.0, 1.0, 0.0, 1.0, 10)
    assert F.efficiencies([pt], 0.0) == ([], {})
    # A level that did not move at about its speed (stuck) gives no efficiency.
    stuck = F.StribeckPoint(0.01, 1e-6, 0.1, 0.0, 1.0, 0.0, 1.0, 10)
    assert F.efficiencies([stuck], 50.0) == ([], {})


def test_figures_of_a_simulate_recording_are_the_closed_forms(tmp_path):
    # The sweep's commands at 1 kHz as simulate's --velocity-csv (zero-order
    # hold: the row at t_k is the command of step k), the recording read with
    # mcap_ros2: axis/joint_states' screw joint (motor torque, rate) and nut joint,
    # velocity_command at its log time. Fast levels as in the model test.
    from helpers import cli_ok
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory
    sets = dict(bearing_viscous=0.0, guide_viscous=0.0)
    p = ScrewParams.from_dict(sets, base=load_preset('tr8x8'))
    prof = make_profile('sweep', p, levels=4, settle=0.3, measure=0.4)
    t = np.arange(int(round(prof.duration / DT))) * DT
    csv = tmp_path / 'sweep.csv'
    csv.write_text('time,velocity\n' + ''.join(f'{float(a)!r},{float(b)!r}\n' for a, b in
                                               zip(t, prof.values(t))))
    out = tmp_path / 'sweep.mcap'
    cli_ok('simulate', '--preset', 'tr8x8', *[a for k, v in sets.items()
                                              for a in ('--set', f'{k}={v}')],
           '--velocity-csv', csv, '--duration', prof.duration, '-o', out, '-q')
    cmd, js = [], []
    with open(out, 'rb') as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        for _s, c, m, d in reader.iter_decoded_messages(
                topics=['/velocity_command', '/axis/joint_states']):
            if c.topic == '/velocity_command':
                cmd.append((m.log_time * 1e-9, d.data))
            else:
                js.append((m.log_time * 1e-9, d.effort[0], d.velocity[0], d.position[1],
                           d.velocity[1]))
    ts, tq, w, x, v = (np.array(col) for col in zip(*js))
    # A state logged at t + dt carries the command logged at t.
    command = F.hold_series([a + DT for a, _b in cmd], [b for _a, b in cmd], ts)
    run = dict(time=ts, command=command, motor_torque=tq, motor_velocity=w, nut_position=x,
               nut_velocity=v)
    fig = F.derived_figures('sweep', run, load=F.axial_load(p))
    th = Thread(p)
    fast = [pt for pt in fig['stribeck']
            if abs(pt.command) / math.sin(th.lam) >= 10 * p.stribeck_velocity]
    assert len(fast) >= 4
    for pt in fast:
        mu = th.mu(pt.command)
        closed = -th.raise_(mu) if pt.command > 0 else th.lower(mu)
        assert pt.torque == pytest.approx(closed, rel=1e-5), (pt.command, pt.torque, closed)
    best = fig['efficiency'][1]
    mu_fast = th.mu(prof.options['v_max'])
    assert best['forward'] == pytest.approx(th.eta(mu_fast), rel=1e-5)
    assert best['backdrive'] == pytest.approx(th.eta_back(mu_fast), rel=1e-5)
