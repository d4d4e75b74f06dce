"""
The ``leadscrew_sim freqresp`` verb: CSV columns, Bode PNG, summary, one-line errors.

The numbers the verb prints are checked against oracles in
test/analysis/test_freqresp_*.py; here: the CSV agrees with the library call
that the verb names (the same numbers written), and bad input gets one line
and a non-zero exit.
"""
import csv
import math
import re

import numpy as np
import pytest

from leadscrew_sim.cli.main import main, VERBS
from leadscrew_sim.core.presets import load_preset

pytestmark = pytest.mark.skipif('freqresp' not in dict(VERBS),
                                reason='the freqresp verb is not registered in cli/main.py')

COLUMNS = ['frequency', 'magnitude_db', 'phase_deg', 'coherence', 'amplitude']


def read_csv(path):
    with open(path) as f:
        rows = list(csv.reader(f))
    return rows[0], rows[1:]


def test_linear_loop_csv_and_margins(tmp_path, capsys):
    out, png = tmp_path / 'l.csv', tmp_path / 'l.png'
    rc = main(['freqresp', '--linear', '--loop', 'velocity', '--quantity', 'L', '--sampling',
               'drive', '--set', 'mu_s=0', '--set', 'mu_k=0', '--fmin', '1', '--fmax', '400',
               '--points', '200', '-o', str(out), '--plot', str(png)])
    assert rc == 0
    text = capsys.readouterr().out
    assert 'phase margin' in text and 'peak sensitivity' in text and 'bandwidth' in text
    head, rows = read_csv(out)
    assert head == COLUMNS and len(rows) == 200
    f = np.array([float(r[0]) for r in rows])
    mag = np.array([float(r[1]) for r in rows])
    assert f[0] == pytest.approx(1.0) and f[-1] == pytest.approx(400.0)
    assert all(r[3] == '' and r[4] == '' for r in rows)     # linear: no coherence, amplitude
    # the velocity loop's L falls through 0 dB once, where the summary puts the crossover
    i = np.nonzero(mag < 0.0)[0][0]
    printed = float(re.search(r'phase margin \S+ deg at (\S+) Hz', text).group(1))
    assert f[i - 1] <= printed <= f[i]
    assert png.read_bytes()[:4] == b'\x89PNG' and png.stat().st_size > 20000


def test_simulated_amplitudes_csv(tmp_path, capsys):
    out = tmp_path / 's.csv'
    rc = main(['freqresp', '--set', 'mu_s=0', '--set', 'mu_k=0', '--input', 'velocity_command',
               '--output', 'motor_velocity', '--fmin', '2', '--fmax', '40', '--points', '4',
               '--amplitude', '1e-3,2e-3', '--workers', '1', '-o', str(out)])
    assert rc == 0
    head, rows = read_csv(out)
    assert head == COLUMNS and len(rows) == 8
    amps = sorted({float(r[4]) for r in rows})
    assert amps == [1e-3, 2e-3]
    # a linear axis: the gain does not depend on the amplitude, coherence 1
    g = {}
    for r in rows:
        g.setdefault(float(r[0]), []).append(float(r[1]))
    assert all(abs(a - b) < 0.01 for a, b in g.values())
    assert all(float(r[3]) > 0.999 for r in rows)
    assert 'gain within 1 dB across the amplitudes' in capsys.readouterr().out


def test_multisine_and_chirp_run(tmp_path):
    for method in ('multisine', 'chirp'):
        out = tmp_path / f'{method}.csv'
        rc = main(['freqresp', '-q', '--method', method, '--set', 'mu_s=0', '--set', 'mu_k=0',
                   '--fmin', '2', '--fmax', '50', '--points', '10', '--amplitude', '1e-3',
                   '-o', str(out)])
        assert rc == 0
        _, rows = read_csv(out)
        assert len(rows) >= 5 and all(math.isfinite(float(r[1])) for r in rows)


@pytest.mark.parametrize('argv, words', [
    (['--fmax', '600'], ['fmax', 'Nyquist', '500']),
    (['--fmax', '500'], ['fmax', 'Nyquist']),
    (['--amplitude', '0'], ['amplitude', '> 0']),
    (['--amplitude', '-0.1'], ['amplitude', '> 0']),
    (['--amplitude', 'abc'], ['amplitude', 'abc']),
    (['--input', 'speed'], ['input', 'speed', 'torque']),
    (['--output', 'nut_angle'], ['output', 'nut_angle', 'motor_angle']),
    (['--loop', 'current'], ['loop', 'current', 'velocity']),
    (['--loop', 'velocity', '--quantity', 'M'], ['quantity', 'M']),
    (['--method', 'prbs'], ['method', 'prbs', 'sine']),
    (['--set', 'nonsense=1'], ['nonsense']),
    (['--linear', '--rest', 'loose'], ['rest', 'loose', 'stuck']),
])
def test_bad_input_one_line(argv, words, capsys):
    rc = main(['freqresp', '-q', '--workers', '1'] + argv)
    err = capsys.readouterr().err
    assert rc != 0
    assert len(err.strip().splitlines()) == 1, err
    for w in words:
        assert w in err, err


def test_default_amplitude_is_positive():
    from leadscrew_sim.analysis.freqresp.measure import default_amplitude
    p = load_preset('tr12x3')
    for kw in (dict(input='torque'), dict(input='velocity_command'),
               dict(input='position_command'), dict(input='external_force'),
               dict(loop='velocity'), dict(loop='position')):
        assert default_amplitude(p, **kw) > 0.0


NOT_A_NUMBER = re.compile(r'\b(nan|inf)\b', re.IGNORECASE)   # 'resonance' holds 'nan'


def stuck_loop_oracle(p, f):
    """
    Return L(f) of the velocity loop with the thread stuck at rest (rigid coupling, no lag).

    Stuck, each nut body moves as x = -r_m cot(lambda) q, its contact deflected by
    -r_m q / (sin cos): the rotor sees the spring k_eq = k r_m^2 / (sin cos)^2 (and the
    contact damping likewise) and the inertia J_m + J_s + m (r_m cot)^2;
    L = K_v (1 + 1 / (s T_i)) s / (J s^2 + c_eq s + k_eq).
    """
    rm = (p.major_diameter - p.pitch / 2.0) / 2.0
    lam = math.atan(p.pitch * p.starts / (2.0 * math.pi * rm))
    g = rm ** 2 / (math.sin(lam) * math.cos(lam)) ** 2
    j = (p.motor_inertia + p.screw_inertia
         + (p.nut_mass + p.payload_mass) * (rm / math.tan(lam)) ** 2)
    s = 2j * math.pi * np.asarray(f)
    c = p.velocity_gain * (1.0 + 1.0 / (s * p.velocity_integral_time))
    return c * s / (j * s ** 2 + p.contact_damping * g * s + p.contact_stiffness * g)


def test_stuck_loop_summary_says_why_never_nan(tmp_path, capsys):
    out = tmp_path / 'stuck.csv'
    rc = main(['freqresp', '--preset', 'tr12x3', '--loop', 'velocity', '--quantity', 'L',
               '--linear', '-o', str(out)])
    assert rc == 0
    text = capsys.readouterr().out
    assert not NOT_A_NUMBER.search(text), text
    assert text.count('the thread is stuck at rest (stiction)') == 1
    assert '--speed V' in text and '--rest free' in text
    assert 'bandwidth: none in 1-100 Hz (|L| stays below 0 dB' in text
    assert 'gain margin: none (the phase never crosses -180 deg in the band)' in text
    assert 'phase margin: none (|L| stays below 0 dB: no crossover in the band)' in text
    # the words are the physics: the stuck rotor is a stiff spring, |L| ~ 1e-5 << 1
    p = load_preset('tr12x3')
    assert p.coupling_stiffness == 0.0 and p.torque_lag == 0.0 and p.mu_s > 0.0
    _, rows = read_csv(out)
    f = np.array([float(r[0]) for r in rows])
    mag = np.array([float(r[1]) for r in rows])
    expect = 20.0 * np.log10(np.abs(stuck_loop_oracle(p, f)))
    assert expect.max() < -40.0
    # 0.05 dB: the guide and bearing viscous terms the oracle leaves out are < 1e-3 of
    # the contact's impedance in 1-100 Hz
    np.testing.assert_allclose(mag, expect, atol=0.05)


@pytest.mark.parametrize('argv, words', [
    (['--input', 'velocity_command', '--output', 'motor_velocity'],
     'bandwidth: none in 1-100 Hz (the gain never falls 3 dB below its low-frequency value)'),
    (['--loop', 'velocity', '--quantity', 'S'],
     'bandwidth: none in 1-100 Hz (|S| stays above -3 dB'),
])
def test_stuck_closed_loop_summary_never_nan(argv, words, capsys):
    rc = main(['freqresp', '--preset', 'tr12x3', '--linear'] + argv)
    assert rc == 0
    text = capsys.readouterr().out
    assert not NOT_A_NUMBER.search(text), text
    assert words in text and text.count('stuck at rest') == 1


def test_sliding_summary_has_figures_and_no_stuck_note(capsys):
    rc = main(['freqresp', '--preset', 'tr12x3', '--linear', '--loop', 'velocity',
               '--speed', '0.01'])
    assert rc == 0
    text = capsys.readouterr().out
    assert not NOT_A_NUMBER.search(text) and 'stuck' not in text
    assert re.search(r'phase margin [0-9.]+ deg at [0-9.]+ Hz', text), text


def test_points_without_a_result_summary_and_csv(tmp_path):
    # a measured L with two points lost to a drive fault and |L| below 0 dB throughout:
    # every figure in words or a number, unknown CSV cells empty
    from leadscrew_sim.analysis.freqresp.output import write_csv
    from leadscrew_sim.analysis.freqresp.response import FrequencyResponse
    from leadscrew_sim.analysis.freqresp.summary import summary_lines
    f = np.geomspace(1.0, 100.0, 200)
    s = 2j * math.pi * f
    wn = 2.0 * math.pi * 10.0
    h = 0.05 * wn ** 2 / (s ** 2 + 2 * 0.05 * wn * s + wn ** 2)
    h[[50, 120]] = np.nan
    r = FrequencyResponse(f, h, np.where(np.isfinite(h), 0.99, np.nan), 0.5, 'velocity_loop',
                          'L', 'sine')
    text = '\n'.join(summary_lines([r]))
    assert not NOT_A_NUMBER.search(text), text
    # the peak found across the lost points: on the grid (steps of 2.3 %), its damping
    # from the half-power width of a 200-point grid (within 20 % of zeta = 0.05)
    fn, zeta = map(float, re.search(r'resonances: (\S+) Hz \(damping (\S+)\)', text).groups())
    assert fn == pytest.approx(10.0, rel=0.025) and zeta == pytest.approx(0.05, rel=0.2)
    assert 'phase margin: none (|L| stays below 0 dB' in text
    assert 'gain margin: none' in text and 'bandwidth: none in 1-100 Hz' in text
    path = tmp_path / 'r.csv'
    write_csv(path, [r])
    _, rows = read_csv(path)
    assert all(r[1] == r[2] == r[3] == '' for r in (rows[50], rows[120]))
    assert not any(NOT_A_NUMBER.search(c) for row in rows for c in row)
    # the phase of the other points: np.angle of H, on one branch (|H| > 0, no wrap here)
    ok = np.isfinite(h)
    phase = np.array([float(row[2] or 'nan') for row in rows])[ok]
    np.testing.assert_allclose(phase, np.degrees(np.angle(h[ok])), atol=1e-9)


def test_simulate_excite_help_lists_every_registered_profile(capsys):
    # the broadband profiles freqresp reads (chirp, multisine) among them
    from leadscrew_sim.analysis.excitation.profiles import PROFILES
    with pytest.raises(SystemExit) as done:
        main(['simulate', '--help'])
    assert done.value.code == 0
    text = ' '.join(capsys.readouterr().out.split())      # argparse wraps the lines
    listed = re.search(r'--excite PROFILE a profile of `leadscrew_sim excite` \(([^)]*)\)', text)
    assert listed, text
    assert set(listed.group(1).split(', ')) == set(PROFILES) >= {'chirp', 'multisine'}


@pytest.mark.parametrize('output', ['L', 'S', 'T', 'motor_velocity'])
@pytest.mark.parametrize('case', ['all lost', 'zero', 'one point'])
def test_summary_without_data_says_so(output, case):
    # every point lost, a zero gain, or a single point: no figure can be formed
    from leadscrew_sim.analysis.freqresp.response import FrequencyResponse
    from leadscrew_sim.analysis.freqresp.summary import summary_lines
    f = np.geomspace(1.0, 100.0, 10)
    h = {'all lost': np.full(10, np.nan + 0j), 'zero': np.zeros(10, complex),
         'one point': np.r_[np.full(9, np.nan), 0.5] + 0j}[case]
    loop = output in ('L', 'S', 'T')
    r = FrequencyResponse(f, h, np.full(10, np.nan), 0.1,
                          'velocity_loop' if loop else 'torque', output, 'sine')
    with np.errstate(all='raise'):           # and no silent division by zero on the way
        text = '\n'.join(summary_lines([r, r]))
    assert not NOT_A_NUMBER.search(text), text
    assert 'bandwidth: none in 1-100 Hz (too few points with a finite gain)' in text
    if loop:
        assert 'margins: none (too few points with a finite, nonzero L)' in text


@pytest.mark.parametrize('argv', [['--linear'], ['--loop', 'velocity'],
                                  ['--linear', '--input', 'position_command']])
def test_stepper_axis_refused_where_the_servo_is_assumed(argv, capsys):
    # the linear model and the loops are the servo drive's: a stepper axis gets one line
    from leadscrew_sim.core.presets import preset_names
    if 'nema23_tr12x3' not in preset_names():
        pytest.skip('the stepper presets come with the stepper drive')
    rc = main(['freqresp', '-q', '--workers', '1', '--preset', 'nema23_tr12x3'] + argv)
    err = capsys.readouterr().err
    assert rc != 0 and len(err.strip().splitlines()) == 1, err
    assert 'drive_type' in err and 'stepper' in err and 'servo' in err
