"""
``leadscrew_sim identify`` gives the same fit, to the bit, under two OpenBLAS kernels.

numpy's bundled OpenBLAS picks a kernel per CPU; ``OPENBLAS_CORETYPE`` makes
one machine round as another would. The recording is the case that showed
the difference: reversals in position mode on tr12x3 with real sensors (a
16-bit encoder, a 1 um scale), sensor seed 11, its parameter record and seed
stripped as a user's bag would be. The same ``identify`` runs in two
processes, one per kernel; their reports (less the wall time) and their
fit files must be identical. The test first checks that the two kernels do
round differently here (an SVD of a fixed matrix); where they do not, it
cannot tell anything and skips.
"""
import hashlib
import os
from pathlib import Path
import subprocess
import sys

from bag_factory import strip_records
from conftest import _has_avx2_fma
from helpers import cli_ok
import pytest
from test_identify_real_sensors import _sets, FIT, REAL, TRUTH

KERNELS = ('Haswell', 'Prescott')

#: Prints a hash of numpy's SVD of a fixed matrix: differs between kernels that round apart.
PROBE = ('import hashlib, numpy as np; a = np.random.default_rng(1).standard_normal((2000, 5)); '
         'print(hashlib.md5(np.linalg.svd(a, compute_uv=False).tobytes()).hexdigest())')


def _env(kernel):
    return dict(os.environ, OPENBLAS_CORETYPE=kernel)


def _probe(kernel):
    out = subprocess.run([sys.executable, '-c', PROBE], env=_env(kernel), check=True,
                         capture_output=True, text=True, timeout=120)
    return out.stdout.strip()


@pytest.mark.skipif(not _has_avx2_fma(), reason='the Haswell kernel needs AVX2 and FMA')
def test_two_openblas_kernels_give_the_same_fit(tmp_path):
    if len({_probe(k) for k in KERNELS}) == 1:
        pytest.skip('the two kernels round alike on this host: nothing to compare')
    rec = tmp_path / 'reversals.mcap'
    cli_ok('simulate', '--preset', 'tr12x3', '--excite', 'reversals', *_sets(TRUTH),
           *_sets(dict(REAL, sensor_seed=11)), '-q', '-o', rec)
    bare = tmp_path / 'bare.mcap'
    strip_records(rec, bare)
    procs = {}
    for k in KERNELS:
        cmd = [sys.executable, '-m', 'leadscrew_sim.cli', 'identify', str(bare), '--preset',
               'tr12x3', '--fit', FIT, '--output-params', str(tmp_path / f'{k}.yaml')]
        procs[k] = subprocess.Popen(cmd, env=_env(k), stdout=subprocess.PIPE,
                                    stderr=subprocess.STDOUT, text=True)
    reports = {}
    for k, p in procs.items():
        out, _ = p.communicate(timeout=600)
        assert p.returncode == 0, out
        reports[k] = [line for line in out.splitlines() if ' s wall' not in line]
    assert reports['Haswell'] == reports['Prescott']
    files = {k: hashlib.sha256(Path(tmp_path / f'{k}.yaml').read_bytes()).hexdigest()
             for k in KERNELS}
    assert files['Haswell'] == files['Prescott']
