"""
One numba cache for every way of running: make, the README's venv commands, ros2 run.

The Makefile's environment and the plain environment the README's venv
commands run in must resolve to the same cache directory, so that a kernel
compiled by ``make setup`` (or any earlier run) is loaded, not compiled
again, by a command typed in the venv. Nothing here is timed: the checks
read numba's own cache hit and miss counts.
"""
import json
import os
from pathlib import Path
import re
import subprocess
import sys

from helpers import REPO

PROBE = r'''
import json, sys
from leadscrew_sim.core.warmup import kernel_ready
from leadscrew_sim.core.engine import kernel
r = kernel_ready()
entry = (kernel.step, kernel.step_held, kernel.run_series)
r['hits'] = sum(len(d.stats.cache_hits) for d in entry)
r['misses'] = sum(len(d.stats.cache_misses) for d in entry)
print(json.dumps(r))
'''


def makefile_env():
    """Return the environment of the Makefile's ``ENV`` line (its NAME=value pairs)."""
    text = (REPO / 'Makefile').read_text()
    line = re.search(r'^ENV := (.*)$', text, re.M).group(1)
    venv = str(Path(sys.prefix))
    out = {}
    for pair in line.split():
        name, _sep, value = pair.partition('=')
        out[name] = value.replace('$(VENV)', venv).replace('$(CURDIR)', str(REPO))
    return out


def probe(env):
    """Run the probe in a fresh interpreter with ``env``; return its report."""
    out = subprocess.run([sys.executable, '-c', PROBE], env=env, cwd=REPO, capture_output=True,
                         text=True, timeout=900)
    assert out.returncode == 0, out.stderr[-2000:]
    return json.loads(out.stdout.strip().splitlines()[-1])


def plain_env():
    """Return the environment of the README's venv block: AMENT_PREFIX_PATH, no numba setting."""
    env = {k: v for k, v in os.environ.items() if not k.startswith('NUMBA_')}
    env['AMENT_PREFIX_PATH'] = str(Path(sys.prefix))
    return env


def test_make_and_the_venv_commands_share_one_cache():
    made = probe(dict(plain_env(), **makefile_env()))          # compiles if it must
    typed = probe(plain_env())
    assert typed['cache_dir'] == made['cache_dir']
    assert typed['misses'] == 0 and typed['hits'] >= 3 and not typed['compiled'], typed


def test_a_venv_command_after_setup_compiles_nothing(tmp_path):
    probe(dict(plain_env(), **makefile_env()))
    out = subprocess.run([sys.executable, '-m', 'leadscrew_sim.cli', 'simulate', '--preset',
                          'tr12x3', '--duration', '0.05', '-o', str(tmp_path / 'a.mcap')],
                         env=plain_env(), cwd=tmp_path, capture_output=True, text=True,
                         timeout=900)
    assert out.returncode == 0, out.stderr
    assert 'compiling the kernel' not in out.stderr, out.stderr
