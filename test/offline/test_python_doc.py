"""
The code blocks of doc/python.md run as written, in a fresh interpreter and an empty directory.

Oracles: each block exits 0, the sweep's nut travels less with more
friction (a monotone law of the torque balance), each fitted mu_k of the
folder example is the value its recording was simulated with (ideal
sensors: to 1e-3), and the overlay wrote a PNG.
"""
import os
from pathlib import Path
import re
import subprocess
import sys

from helpers import REPO


def test_the_code_blocks_of_doc_python_run(tmp_path):
    """Every ```python block of doc/python.md, in order, in one fresh process."""
    text = (REPO / 'doc' / 'python.md').read_text()
    blocks = re.findall(r'```python\n(.*?)```', text, re.S)
    assert len(blocks) == 4, len(blocks)
    script = '\n'.join(b for b in blocks if 'help(' not in b)
    r = subprocess.run([sys.executable, '-c', script], capture_output=True, text=True,
                       timeout=600, cwd=tmp_path, env=dict(os.environ, MPLBACKEND='Agg'))
    assert r.returncode == 0, r.stderr[-3000:]
    travel = [float(m) for m in re.findall(r'nut at (-?[\d.]+) mm', r.stdout)]
    assert len(travel) == 3 and abs(travel[0]) > abs(travel[1]) > abs(travel[2]), r.stdout
    fits = dict(re.findall(r'^(axis\d)\.mcap (?:identified|exact data|not identifiable) '
                           r'([\d.]+)', r.stdout, re.M))
    assert abs(float(fits['axis0']) - 0.12) < 1e-3 and abs(float(fits['axis1']) - 0.18) < 1e-3, \
        r.stdout
    png = Path(tmp_path / 'twins.png')
    assert png.read_bytes()[:8] == b'\x89PNG\r\n\x1a\n'


def test_the_code_block_of_doc_ageing_runs(tmp_path):
    """doc/ageing.md's example wears the axis (backlash above the set 100 um) and carries on."""
    text = (REPO / 'doc' / 'ageing.md').read_text()
    blocks = re.findall(r'```python\n(.*?)```', text, re.S)
    assert len(blocks) == 1, len(blocks)
    r = subprocess.run([sys.executable, '-c', blocks[0]], capture_output=True, text=True,
                       timeout=600, cwd=tmp_path)
    assert r.returncode == 0, r.stderr[-3000:]
    m = re.search(r'backlash ([\d.]+) um', r.stdout)
    assert m and float(m[1]) > 100.0, r.stdout
    assert 'carried on: True' in r.stdout and 'starts worn: True' in r.stdout
    assert (tmp_path / 'second.mcap').stat().st_size > 0
