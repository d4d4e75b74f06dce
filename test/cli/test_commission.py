"""
``leadscrew_sim commission`` on ``simulate --excite commission`` with the axis's own sensors.

The oracle is the parameter set the test gives ``simulate`` (tr12x3 with
its friction moved by the identification tests' factors, a 16-bit encoder
with half a count of noise, a 1 um scale with 0.5 um of noise): the fit
against it with the identify tolerances, the efficiencies and the
breakaway torques against the thread's closed forms, the loop margins
against python-control's on the linear model built here, the held-out
error against the noise. Then the page in headless Chromium.
"""
import json
import math
import resource
import shutil
import socket
import subprocess
import time

from helpers import cli, cli_ok
from leadscrew_sim import load_preset
import numpy as np
import pytest
import yaml

#: The friction truth against the preset's start (the identification tests' factors).
FACTORS = dict(mu_s=1.25, mu_k=0.8, stribeck_velocity=1.3)
#: The axis's own sensors (as test_identify_sweep).
SENSORS = dict(encoder_counts=2 ** 16, encoder_noise=0.5 * 2 * np.pi / 2 ** 16,
               scale_resolution=1e-6, scale_noise=5e-7, sensor_seed=11)
#: The identification issue's tolerances: relative.
TOLERANCE = dict(mu_s=0.02, mu_k=0.01, stribeck_velocity=0.10)
#: The page's sections, by anchor.
SECTIONS = ('axis', 'parameters', 'twin', 'friction', 'backlash', 'frequency-response',
            'stability', 'iso230', 'stepper', 'undetermined')


def cli_fails(*args):
    """Run the CLI and assert it failed with exit status 1; return the CompletedProcess."""
    r = cli(*args)
    assert r.returncode == 1 and 'Traceback' not in r.stderr, r.stdout + r.stderr
    return r


def _truth():
    p0 = load_preset('tr12x3')
    values = {n: getattr(p0, n) * f for n, f in FACTORS.items()}
    values.update(SENSORS)
    return values


@pytest.fixture(scope='module')
def commissioned(tmp_path_factory):
    """Return (recording, output dir, report dict, stderr) of the commission of tr12x3."""
    d = tmp_path_factory.mktemp('commission')
    rec, out = d / 'run.mcap', d / 'out'
    sets = [a for n, v in _truth().items() for a in ('--set', f'{n}={v!r}')]
    cli_ok('simulate', '--preset', 'tr12x3', '--excite', 'commission', *sets, '-q', '-o', rec)
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    r = cli_ok('commission', rec, '-o', out)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    # its CPU time, printed: speed is measured in bench/bench_commission.py, not asserted here
    cpu = (after.ru_utime + after.ru_stime) - (before.ru_utime + before.ru_stime)
    print(f'commission: {cpu:.1f} s of CPU')
    with open(out / 'report.json') as fh:
        report = json.load(fh)
    return rec, out, report, r.stderr, cpu


def test_fit_yaml_holds_the_truth_and_loads(commissioned, tmp_path):
    """fit.yaml: a /** parameter file with the identified values within the tolerances."""
    rec, out, report, _err, _wall = commissioned
    text = (out / 'fit.yaml').read_text()
    doc = yaml.safe_load(text)
    values = doc['/**']['ros__parameters']
    truth = _truth()
    for name, tol in TOLERANCE.items():
        assert abs(values[name] - truth[name]) <= tol * truth[name], (name, values[name])
    # identified values only: nothing else but the preset it goes over
    assert set(values) == {'preset', *TOLERANCE}
    # the intervals of the report hold the truth
    for row in report['sections']['identify']['parameters']:
        assert row['lower'] <= truth[row['name']] <= row['upper'], row
    # simulate loads it (as the node's --params-file does)
    cli_ok('simulate', '--params', out / 'fit.yaml', '--duration', '0.01', '-q',
           '-o', tmp_path / 'check.mcap')


def test_progress_per_stage_and_the_segments(commissioned):
    """Every stage says it ran on stderr; the segments are the profile's parts."""
    _rec, _out, report, err, _wall = commissioned
    for stage in ('identify', 'twin', 'friction', 'backlash', 'frequency response',
                  'stability', 'iso230', 'stepper'):
        assert f'] {stage} done in' in err, stage
    from leadscrew_sim.analysis.excitation.profiles import make_profile
    prof = make_profile('commission', load_preset('tr12x3', **_truth()))
    seg = report['sections']['axis']['segments']
    assert list(seg) == [n for n, _a, _b in prof.windows()]
    for n, a, b in prof.windows():
        assert seg[n] == pytest.approx([a, b], abs=1e-9)


def test_the_play_of_the_loaded_vertical_axis_is_not_fitted(commissioned):
    """The vertical tr12x3's load holds the nut on one flank: no backlash fit, and why."""
    from bag_factory import sim_states
    rec, out, report, _err, _cpu = commissioned
    # Oracle, the physics: the nut leaves the flank its weight presses only when the axis
    # accelerates downward faster than g sin(beta). The measured nut velocity (a 1 um
    # scale, differenced over 20 ms) bounds the reversals' acceleration far below that.
    p = load_preset('tr12x3', **_truth())
    a, b = report['sections']['axis']['segments']['reversals']
    stamps, _pos, vel, _eff = sim_states(rec)
    t = stamps / 1e9
    k = (t >= a) & (t <= b)
    v = np.convolve(vel[k, 1], np.ones(20) / 20, mode='valid')
    accel = np.max(np.abs(np.diff(v[::20]))) / 0.02
    print(f'reversals: largest nut acceleration {accel:.3g} m/s^2 against g sin(beta) '
          f'{9.81 * math.sin(p.inclination):.3g} m/s^2')
    assert accel < 0.5 * 9.81 * math.sin(p.inclination)
    section = report['sections']['backlash']
    assert not section['backlash_fitted'] and section['backlash_fit']['value'] is None, section
    assert 'does not show' in section['backlash_fit']['reason'], section
    assert any('one flank' in c for c in section['cannot']), section['cannot']
    values = yaml.safe_load((out / 'fit.yaml').read_text())['/**']['ros__parameters']
    assert 'backlash' not in values, values


def efficiency_closed_forms(truth, v):
    """
    Return (forward, back-driving) efficiency of the truth's axis at nut speed ``v`` [m/s].

    The motor torque of steady sliding is the thread's, W' r (mu' + tan l) /
    (1 - mu' tan l) raising and W' r (mu' - tan l) / (1 + mu' tan l)
    lowering, with W' the load less the guide's viscous force c |v| against
    the motion and mu' the truth's law at the sliding speed, plus the
    bearing's viscous torque b w (w = 2 pi v / l). The efficiencies are the
    load power over the motor power: W r tan l / T and -T / (W r tan l).
    """
    lam, r = truth.lead_angle, truth.r_m
    omega = 2 * math.pi * v / truth.lead
    vs = v / math.sin(lam)
    mu = truth.thread_factor * (truth.mu_k + (truth.mu_s - truth.mu_k) * math.exp(
        -(vs / truth.stribeck_velocity) ** truth.stribeck_exponent)) + \
        truth.thread_factor * truth.mu_viscous * vs
    t = math.tan(lam)
    w = truth.moving_mass * truth.gravity
    up_torque = (w + truth.guide_viscous * v) * r * (mu + t) / (1 - mu * t) + \
        truth.bearing_viscous * omega
    down_torque = (w - truth.guide_viscous * v) * r * (mu - t) / (1 + mu * t) + \
        truth.bearing_viscous * omega
    return w * r * t / up_torque, -down_torque / (w * r * t)


def test_friction_figures_against_the_closed_forms(commissioned):
    """
    Efficiencies and breakaway torques against the axis's closed forms of the truth.

    At the fastest level the efficiencies (:func:`efficiency_closed_forms`)
    within 3 % (the level's mean speed carries the scale's noise). The
    breakaway torques: at least the static closed form (stiction holds until
    it is passed), at most 5 % above it (the ramp runs on while the nut moves
    the 5 sigma the detection needs).
    """
    _rec, _out, report, _err, _wall = commissioned
    from leadscrew_sim.analysis.excitation.profiles import static_breakaway
    truth = load_preset('tr12x3', **_truth())
    f = report['sections']['friction']
    fwd, back = efficiency_closed_forms(truth, f['efficiency_thread']['speed'])
    assert f['efficiency_measured']['forward'] == pytest.approx(fwd, rel=0.03)
    assert f['efficiency_measured']['backdrive'] == pytest.approx(back, rel=0.03)
    up, down = static_breakaway(truth)
    assert up <= f['breakaway']['+'] <= up * 1.05
    assert down * 1.05 <= f['breakaway']['-'] <= down
    assert f['self_locking'] is True


def test_loop_margins_against_python_control(commissioned):
    """
    The report's margins are python-control's on the linear model of the calibrated set.

    The test builds the velocity and position loops' L (the same linear
    model, at rest with the thread friction left out, sampled at the drive
    period) up to the drive's Nyquist frequency and takes control's
    stability_margins on it (a frequency-response-data system): gain margin
    within 1 %, phase margin within 1 deg, crossover within 1 %.
    """
    control = pytest.importorskip('control')
    _rec, out, report, _err, _wall = commissioned
    from leadscrew_sim.analysis.freqresp.measure import linear_response
    from leadscrew_sim.core.drive_control import drive_period
    values = yaml.safe_load((out / 'fit.yaml').read_text())['/**']['ros__parameters']
    values.pop('preset')
    p = load_preset('tr12x3', **dict(SENSORS, **values))
    td = drive_period(p, 1e-3)
    s = report['sections']['frequency response']
    assert s['drive_nyquist_hz'] == pytest.approx(0.5 / td)
    f = np.geomspace(0.1, 0.4999 / td, 4000)
    for loop in ('velocity', 'position'):
        lg = linear_response(p, loop=loop, quantity='L', sampling='drive', frequency=f,
                             dt=1e-3, rest='free').loop_gain
        sys = control.frd(lg, 2 * np.pi * f)
        gm, pm, _sm, wpc, wgc, _wms = control.stability_margins(sys)
        m = s['loops'][loop]
        assert m['phase_margin_deg'] == pytest.approx(pm, abs=1.0), loop
        assert m['crossover'] == pytest.approx(wgc / (2 * np.pi), rel=0.01), loop
        if math.isfinite(gm) and wpc / (2 * np.pi) < 0.4999 / td:
            assert 10 ** (m['gain_margin_db'] / 20) == pytest.approx(gm, rel=0.01), loop
        else:
            assert m['gain_margin_db'] is None, loop
        assert m['ms'] == pytest.approx(np.max(np.abs(1 / (1 + lg))), rel=1e-6), loop


def test_held_out_error_at_the_noise_level(commissioned):
    """
    The held-out reversals: the twin's error is a few noise levels; the sentence says it.

    The oracle of the comparison itself: the recording's own parameters
    (the truth) re-simulated the same way give the noise level (RMS / sigma
    in [0.8, 1.6]: the scale's quantisation and noise, sigma as identify
    knows it). The calibrated set differs from the truth within its
    intervals; its error stays below 8 sigma RMS. With other noise draws the
    truth misses by the closed loop's floor (the drive's loops over noisy
    sensors decide where the thread sticks): the report's floor is within a
    factor 2 of that miss, the calibrated twin within 3 times it. Fits
    within their intervals land anywhere in that chaotic spread: over sensor
    seeds 7, 11, 15, 19 and 23 of this recording, with the fit started from
    the preset and from the breakaway's mu_s, the held-out error was 0.90
    to 2.70 times the report's floor.
    """
    rec, _out, report, _err, _wall = commissioned
    s = report['sections']['twin']
    h = s['held_out']
    assert h['rms_over_noise'] < 8.0, h
    assert f'to {h["rms_um"]:.3g} um RMS on data it was not fitted to' in s['sentence']
    held_out_rms = _held_out_rms(rec, s['parts']['reversals']['window'])
    sigma = s['noise_um'] * 1e-6
    assert 0.8 <= held_out_rms({}) / sigma <= 1.6
    # with other noise draws the truth itself misses by the closed loop's floor: the
    # report's floor (three calibrated twins of other draws) within a factor 2 of it, and
    # the calibrated twin within 3 times it
    other = float(np.mean([held_out_rms({'sensor_seed': seed}) for seed in (1, 2)]))
    assert 0.5 <= h['floor_um'] * 1e-6 / other <= 2.0, (h, other)
    assert h['rms_um'] * 1e-6 <= 3.0 * other, (h, other)


def test_the_noise_level_needs_the_exact_parameters(commissioned):
    """
    Only the recording's exact parameters reach the noise level on the held-out reversals.

    Why the held-out figure is judged against the closed loop's floor, not
    against the noise: the truth re-simulated with the recorded noise draw
    reads at the noise level, but the same truth with one friction
    parameter moved by 1e-8 of itself (far below any interval) decorrelates
    where the position loop, acting on noisy quantised readings, lets the
    thread stick at each target. Its error is then at least 1.5 times the
    exact truth's (runs: 1.8 to 2.4 times): the noise level is out of reach
    of any fit, and the headline's multiple of the floor is the figure a
    fit can be held to.
    """
    rec, _out, report, _err, _wall = commissioned
    held_out_rms = _held_out_rms(rec, report['sections']['twin']['parts']['reversals']['window'])
    truth = _truth()
    exact = held_out_rms({})
    for name in TOLERANCE:
        moved = held_out_rms({name: truth[name] * (1.0 + 1e-8)})
        assert moved >= 1.5 * exact, (name, moved, exact)


def _held_out_rms(rec, window):
    """
    Return f(overrides): the RMS [m] of the recorded nut reading less a re-simulation's nut.

    The re-simulation is ``resim``'s of the recording with the parameter
    overrides (none: the recording's own truth and noise draw), compared at
    the axis/joint_states stamps in ``window`` [s].
    """
    from leadscrew_sim.io import cdr as C
    from leadscrew_sim.offline.options import open_recording
    from leadscrew_sim.offline.replay.resim import Resim
    r = open_recording(rec)
    rows = [(st / 1e9, pos[1]) for _t, tp, data in r.messages if tp == '/axis/joint_states'
            for st, _n, pos, _v, _e in [C.decode_joint_state(data)]]
    ts, xs = np.array(rows).T
    k = (ts >= window[0]) & (ts <= window[1])

    def rms(overrides):
        sim = Resim(r, overrides)
        x = sim.replay()['nut_position']
        t = (np.arange(len(x)) + 1) * sim.dt_ns / 1e9
        e = xs[k] - np.interp(ts[k], t, x)
        return float(np.sqrt(np.mean(e ** 2)))
    return rms


def test_the_mixed_run_re_simulates_bit_for_bit(commissioned):
    """
    The commission run of simulate, a topic per part, is what resim makes of its recorded commands.

    The true nut position of sim/joint_states equals the re-simulation's bit for
    bit: every part's commands passed the node's rules, the breakaway's too.
    """
    rec, _out, _report, _err, _cpu = commissioned
    from leadscrew_sim.io import cdr as C
    from leadscrew_sim.offline.options import open_recording
    from leadscrew_sim.offline.replay.resim import Resim
    r = open_recording(rec)
    states = [C.decode_joint_state(d) for _t, tp, d in r.messages if tp == '/sim/joint_states']
    i = list(states[0][1]).index('nut_joint')
    recorded = np.array([s[2][i] for s in states])
    assert recorded.tobytes() == Resim(r).replay()['nut_position'].tobytes()


def test_missing_segments_are_named(tmp_path):
    """A recording with the reversals only: a report saying what is missing and what it adds."""
    rec = tmp_path / 'rev.mcap'
    cli_ok('simulate', '--preset', 'tr12x3', '--excite', 'reversals', '-q', '-o', rec)
    cli_ok('commission', rec, '-o', tmp_path / 'out', '-q')
    report = json.loads((tmp_path / 'out' / 'report.json').read_text())
    axis = report['sections']['axis']
    assert list(axis['segments']) == ['reversals']
    assert [m['part'] for m in axis['missing']] == ['sweep', 'breakaway', 'chirp', 'iso230']
    assert all(m['would_add'] for m in axis['missing'])
    lines = report['sections']['undetermined']['lines']
    assert any('missing segment sweep' in x for x in lines)
    assert report['sections']['identify']['parameters'] == []
    assert 'nothing identified' in (tmp_path / 'out' / 'fit.yaml').read_text()


def test_too_short_and_unmappable_give_one_line(tmp_path):
    """A 0.5 s recording and a file that is not a leadscrew_sim recording: one error line."""
    short = tmp_path / 'short.mcap'
    cli_ok('simulate', '--preset', 'tr12x3', '--velocity', '0.001', '--duration', '0.5',
           '-q', '-o', short)
    r = cli_fails('commission', short, '-o', tmp_path / 'o1')
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith('leadscrew_sim: error:'), r.stderr
    assert 'too short' in lines[0] or 'no commission part' in lines[0]
    bad = tmp_path / 'bad.mcap'
    bad.write_bytes(b'not an mcap file at all')
    r = cli_fails('commission', bad, '-o', tmp_path / 'o2')
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith('leadscrew_sim: error:'), r.stderr


def _free_port():
    with socket.socket() as s:
        s.bind(('127.0.0.1', 0))
        return s.getsockname()[1]


def _chromium():
    for name in ('chromium', 'chromium-browser', 'google-chrome'):
        path = shutil.which(name)
        if path:
            return path
    return None


def test_page_in_headless_chromium(commissioned, tmp_path):
    """
    report.html in a real browser: every image decodes, no script error, every section there.

    Headless Chromium over the DevTools protocol (websocket-client): the page
    loads from file:// with the network off, each <img> has naturalWidth > 0,
    no exception was thrown, the ten sections are present, and a screenshot
    is taken (pytest's tmp dir).
    """
    exe = _chromium()
    if exe is None:
        pytest.skip('Chromium is not installed (Debian package chromium; .ci/run installs it)')
    websocket = pytest.importorskip('websocket', reason='websocket-client is not installed')
    import urllib.request
    _rec, out, _report, _err, _wall = commissioned
    port = _free_port()
    proc = subprocess.Popen([exe, '--headless', '--no-sandbox', '--disable-gpu',
                             f'--remote-debugging-port={port}', f'--user-data-dir={tmp_path}/u',
                             '--window-size=1200,900', 'about:blank'],
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        end = time.monotonic() + 30
        targets = None
        while time.monotonic() < end:
            try:
                with urllib.request.urlopen(f'http://127.0.0.1:{port}/json/list') as r:
                    targets = [t for t in json.load(r) if t.get('type') == 'page']
                if targets:
                    break
            except OSError:
                pass
            time.sleep(0.2)
        assert targets, 'Chromium did not open its DevTools port'
        ws = websocket.create_connection(targets[0]['webSocketDebuggerUrl'], timeout=30)
        ids = iter(range(1, 10 ** 6))
        events = []

        def call(method, **params):
            i = next(ids)
            ws.send(json.dumps({'id': i, 'method': method, 'params': params}))
            while True:
                msg = json.loads(ws.recv())
                if msg.get('id') == i:
                    return msg.get('result', {})
                events.append(msg)

        call('Runtime.enable')
        call('Page.enable')
        call('Network.enable')
        call('Network.emulateNetworkConditions', offline=True, latency=0,
             downloadThroughput=0, uploadThroughput=0)
        call('Page.navigate', url=(out / 'report.html').as_uri())
        end = time.monotonic() + 20
        while time.monotonic() < end:
            r = call('Runtime.evaluate', expression='document.readyState === "complete" && '
                     'Array.from(document.images).every(i => i.complete)', returnByValue=True)
            if r['result'].get('value'):
                break
            time.sleep(0.1)
        r = call('Runtime.evaluate', returnByValue=True, expression=(
            'JSON.stringify({imgs: Array.from(document.images).map(i => i.naturalWidth), '
            'ids: Array.from(document.querySelectorAll("section")).map(s => s.id), '
            'h: document.documentElement.scrollHeight})'))
        page = json.loads(r['result']['value'])
        # twin, Stribeck, reversals, Bode, stability map (no iso230 part, not a stepper)
        assert len(page['imgs']) == 5 and all(w > 0 for w in page['imgs']), page['imgs']
        assert page['ids'] == list(SECTIONS)
        call('Emulation.setDeviceMetricsOverride', width=1200, height=min(page['h'], 16000),
             deviceScaleFactor=1, mobile=False)
        shot = call('Page.captureScreenshot', format='png', captureBeyondViewport=True)
        import base64
        png = tmp_path / 'report.png'
        png.write_bytes(base64.b64decode(shot['data']))
        assert png.stat().st_size > 10000
        errors = [e for e in events if e.get('method') == 'Runtime.exceptionThrown']
        assert not errors, errors
        requests = [e['params']['request']['url'] for e in events
                    if e.get('method') == 'Network.requestWillBeSent'
                    and not e['params']['request']['url'].startswith(('file:', 'data:'))]
        assert not requests, requests
        ws.close()
    finally:
        proc.terminate()
        proc.wait(timeout=10)
