"""
The ``leadscrew_sim stability`` verb: its table, summary and map, its one-line errors.

An interrupted run (KeyboardInterrupt in the middle of the cases) still writes
a valid CSV: the finished rows, the rest marked as not run.
"""
import csv

import pytest

from leadscrew_sim.analysis.stability import executors
from leadscrew_sim.analysis.stability.grid import COLUMNS
from leadscrew_sim.analysis.stability.table import INTERRUPTED, stability_table
from leadscrew_sim.cli.main import main, VERBS
from leadscrew_sim.core.presets import load_preset

pytestmark = pytest.mark.skipif('stability' not in dict(VERBS),
                                reason='the stability verb is not registered in cli/main.py')


def test_verb_table_summary_and_map(tmp_path, capsys):
    """A speed axis: the CSV columns of interfaces.md, the summary, a PNG."""
    out, png = tmp_path / 'm.csv', tmp_path / 'm.png'
    rc = main(['stability', '--preset', 'stick_slip', '--drive', 'ideal', '--grid',
               'speed=3e-4:4e-3:4:log', '--duration', '0.3', '--workers', '1',
               '-o', str(out), '--plot', str(png)])
    assert rc == 0
    text = capsys.readouterr().out
    assert 'linear boundary along speed' in text and 'worst case' in text
    with open(out) as f:
        rows = list(csv.reader(f))
    assert rows[0] == ['speed'] + list(COLUMNS)
    assert len(rows) == 5
    assert png.stat().st_size > 10000 and png.read_bytes()[:4] == b'\x89PNG'


@pytest.mark.parametrize('argv, word', [
    (['--grid', 'bogus=0:1:3', '--speed', '1e-3'], 'bogus'),
    (['--grid', 'coupling_damping=-1:1:3', '--speed', '1e-3'], 'coupling_damping'),
    (['--grid', 'mu_k=0.1:0.2:1', '--speed', '1e-3'], 'minimum 2'),
    (['--grid', 'mu_k=0.1:0.2:2', '--grid', 'mu_s=0.2:0.3:2', '--grid',
      'bearing_viscous=0:1e-4:2', '--grid', 'guide_viscous=0:1:2', '--speed', '1e-3'],
     'at most 3'),
    (['--speed', '0'], 'speed'),
    (['--set', 'nonsense=1', '--speed', '1e-3'], 'nonsense'),
])
def test_bad_input_one_line(argv, word, capsys):
    """Bad input: one line on stderr naming the parameter, exit status 1."""
    rc = main(['stability', '--preset', 'stick_slip', '-q', '--workers', '1'] + argv)
    err = capsys.readouterr().err
    assert rc == 1
    assert len(err.strip().splitlines()) == 1 and word in err


def test_interrupted_run_leaves_valid_csv(tmp_path, monkeypatch):
    """Ctrl-C after the first batch: the finished rows, the rest marked, a valid CSV."""
    calls = []
    real = executors.run_batch

    def interrupted(*args):
        calls.append(1)
        if len(calls) > 1:
            raise KeyboardInterrupt
        return real(*args)

    monkeypatch.setattr(executors, 'run_batch', interrupted)
    out = tmp_path / 'i.csv'
    res = stability_table(load_preset('stick_slip'), ['speed=1e-3:4e-3:8'], method='linear',
                          workers=1, csv_path=out)
    assert not res['complete']
    with open(out) as f:
        rows = list(csv.DictReader(f))
    assert len(rows) == 8
    done = [r for r in rows if r['error'] != INTERRUPTED]
    assert 0 < len(done) < 8 and all(r['mechanism'] for r in done)
