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
