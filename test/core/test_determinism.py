"""
Bit-identical results whatever numba's cache holds: a fresh compile and a cached load agree.

numba compiles each kernel function into every caller's object code; if the
compiler were free to fuse or reorder floating-point operations, each copy
could round differently and the result would depend on which copy a process
runs (compiled now, or loaded from the cache). Two processes share one new
cache directory: the first compiles, the second loads; a third runs the
kernel as plain Python (NUMBA_DISABLE_JIT), the reference of IEEE 754
arithmetic operation by operation. All three must give the same SHA-256, for
the servo presets and for a stepper that loses steps.
"""
import os
import subprocess
import sys

import pytest

SCRIPT = r'''
import hashlib, math, sys
import numpy as np
from leadscrew_sim import LeadScrewModel, load_preset
n = int(sys.argv[1])
h = hashlib.sha256()
for name in ('anti_backlash', 'stick_slip'):
    p = load_preset(name)
    t = np.arange(n) * 1e-3
    m = LeadScrewModel(p, dt=1e-3)
    res = m.run(0.5 * p.max_torque * np.sin(2 * math.pi * t))
    for key in sorted(res):
        h.update(np.ascontiguousarray(res[key]).tobytes())
    m.advance(0.1)
    h.update(m.state.tobytes())
# a stepper stepped beyond its pull-out at once: it loses steps (stepper.py's code paths)
p = load_preset('nema17_tr8x8', payload_mass=8.0, max_step_rate=12000.0,
                step_acceleration=1e6)
m = LeadScrewModel(p, dt=1e-3)
res = m.run(None, commands=np.tile([1.0, np.nan, p.hand_sign * 8000.0 * p.step_angle, np.nan],
                                   (n // 3, 1)))
assert res['lost_full_steps'][-1] != 0
for key in sorted(res):
    h.update(np.ascontiguousarray(res[key]).tobytes())
h.update(m.state.tobytes())
print(h.hexdigest())
'''


def run(env, n):
    out = subprocess.run([sys.executable, '-c', SCRIPT, str(n)], env=env, capture_output=True,
                         text=True, timeout=900, cwd=os.path.dirname(env['NUMBA_CACHE_DIR']))
    assert out.returncode == 0, out.stderr[-2000:]
    return out.stdout.strip()


@pytest.mark.slow
def test_fresh_compile_cached_load_and_plain_python_agree(tmp_path):
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path / 'numba_cache'))
    n = 300    # plain Python runs about 10^4 substeps per second: keep it short
    compiled = run(env, n)
    assert any((tmp_path / 'numba_cache').rglob('*.nbi')), 'numba wrote no cache'
    cached = run(env, n)
    plain = run(dict(env, NUMBA_DISABLE_JIT='1'), n)
    assert compiled == cached == plain


PROBE = r'''
import sys
from leadscrew_sim import LeadScrewModel, load_preset
from leadscrew_sim.core.engine import kernel
m = LeadScrewModel(load_preset('tr12x3'))
m.advance(0.1)
print(len(kernel.step.stats.cache_hits), len(kernel.step.stats.cache_misses))
'''


@pytest.mark.slow
def test_a_change_of_a_layout_constant_is_never_served_stale_from_the_cache(tmp_path):
    # numba keys a cache entry on its own source file; layout.py's constants are frozen
    # into kernel.py's code, so an edit of layout.py alone must still recompile kernel.py.
    import shutil
    from helpers import REPO
    pkg = tmp_path / 'src' / 'leadscrew_sim'
    shutil.copytree(REPO / 'leadscrew_sim', pkg, ignore=shutil.ignore_patterns('__pycache__'))
    (tmp_path / 'src' / 'config').symlink_to(REPO / 'config')
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path / 'cache'),
               PYTHONPATH=str(tmp_path / 'src'))

    def probe():
        out = subprocess.run([sys.executable, '-c', PROBE], env=env, cwd=tmp_path,
                             capture_output=True, text=True, timeout=900)
        assert out.returncode == 0, out.stderr[-2000:]
        hits, misses = map(int, out.stdout.split())
        return hits, misses
    assert probe() == (0, 1)          # compiled
    assert probe() == (1, 0)          # loaded from the cache
    with open(pkg / 'core' / 'engine' / 'layout.py', 'a') as fh:
        fh.write('\n# an edit of layout.py alone\n')
    assert probe() == (0, 1)          # compiled again, not served stale
    assert probe() == (1, 0)
