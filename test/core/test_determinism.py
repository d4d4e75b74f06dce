"""
Bit-identical results whatever numba's cache holds: a fresh compile and a cached load agree.

numba compiles each kernel function into every caller's object code; if the
compiler were free to fuse or reorder floating-point operations, each copy
could round differently and the result would depend on which copy a process
runs (compiled now, or loaded from the cache). Two processes share one new
cache directory: the first compiles, the second loads; a third runs the
kernel as plain Python (NUMBA_DISABLE_JIT), the reference of IEEE 754
arithmetic operation by operation. All three must give the same SHA-256.
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
print(h.hexdigest())
'''


def run(env, n):
    out = subprocess.run([sys.executable, '-c', SCRIPT, str(n)], env=env, capture_output=True,
                         text=True, timeout=900)
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
