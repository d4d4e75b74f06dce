"""
The offline tools as Python calls (``import leadscrew_sim as ls``), run in a fresh process.

The issue's example runs as a user's script would, in its own interpreter:
simulate with a value of mu_s chosen here, open the recording, identify,
commission; and a bad value raises a LeadscrewError naming the parameter.
Oracles: the value chosen here (the recording has ideal sensors, so the fit
must return it to the fit's resolution), the tick period 1 / update rate,
and the files the commissioning wrote, read back with json and yaml.
"""
import json
import os
from pathlib import Path
import subprocess
import sys

import yaml

SCRIPT = r'''
import json, sys
import numpy as np
import leadscrew_sim as ls
out = sys.argv[1]
run = ls.simulate('tr12x3', excite='commission', set={'mu_s': 0.25},
                  output=out + '/run.mcap')
rec = ls.open_recording(out + '/run.mcap')
fit = ls.identify(rec, fit=['mu_s', 'mu_k', 'stribeck_velocity'])
com = ls.commission(rec, out + '/com')
try:
    ls.simulate('tr12x3', set={'mu_k': -1}, duration=0.1)
    bad = None
except ls.LeadscrewError as exc:
    bad = [type(exc).__name__, str(exc)]
print(json.dumps(dict(
    path=run.path, n=len(run.time), n_x=len(run.nut_position), steps=run.steps,
    dt=float(np.median(np.diff(run.time))), rate=run.rate,
    x_finite=bool(np.isfinite(run.nut_position).all()),
    values=fit.values, intervals=fit.intervals, verdicts=fit.verdicts, misfit=fit.misfit,
    report_format=com.report['format'], sections=sorted(com.report['sections']),
    com_fit=None if com.fit is None else com.fit.values, bad=bad)))
'''


def test_the_issue_example_in_a_fresh_process(tmp_path):
    """simulate, open_recording, identify, commission: named fields; a bad value is named."""
    env = dict(os.environ)
    r = subprocess.run([sys.executable, '-c', SCRIPT, str(tmp_path)], capture_output=True,
                       text=True, timeout=600, env=env)
    assert r.returncode == 0, r.stderr[-3000:]
    got = json.loads(r.stdout.strip().splitlines()[-1])
    # simulate: a tick per step at 1 / update rate, the file where it was asked for
    assert got['path'] == str(tmp_path / 'run.mcap') and Path(got['path']).stat().st_size > 0
    assert got['n'] == got['n_x'] == got['steps'] > 1000 and got['x_finite'], got
    assert abs(got['dt'] - 1.0 / got['rate']) < 1e-9, got
    # identify: ideal sensors, so the fit returns the chosen mu_s to its resolution
    assert set(got['values']) == {'mu_s', 'mu_k', 'stribeck_velocity'}
    assert abs(got['values']['mu_s'] - 0.25) < 1e-4, got['values']
    assert set(got['verdicts'].values()) <= {'identified', 'exact data', 'not identifiable'}
    for name, iv in got['intervals'].items():
        assert iv is None or (len(iv) == 2 and iv[0] <= got['values'][name] <= iv[1]), iv
    assert set(got['misfit']) >= {'screw_angle', 'nut_position'}
    # commission: the report is the one written as report.json, and fit.yaml was written
    written = json.loads((tmp_path / 'com' / 'report.json').read_text())
    assert written['format'] == got['report_format']
    assert sorted(written['sections']) == got['sections']
    fitted = yaml.safe_load((tmp_path / 'com' / 'fit.yaml').read_text())
    assert fitted, 'fit.yaml is empty'
    assert got['com_fit'] is not None and abs(got['com_fit']['mu_s'] - 0.25) < 1e-3
    # the bad value: a LeadscrewError subclass whose message names mu_k, -1 and the range
    kind, message = got['bad']
    assert 'mu_k' in message and '-1' in message and '[0.0, 2.0]' in message, message
