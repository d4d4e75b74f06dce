"""
The verbs' ``--help``, through the venv's ``bin/leadscrew_sim`` link as the README runs it.

Every option has a help text, every verb ``-q``, every verb that writes a
file ``-o``, no verb shows ``--rate``, and the old ``--rate`` still works
with one deprecation line on stderr.
"""
import os
import re
import subprocess

from helpers import REPO
from leadscrew_sim.cli.main import VERBS
import pytest

#: The venv's link to the installed executable (make setup).
EXE = REPO / '.venv' / 'bin' / 'leadscrew_sim'
#: The verbs that write a file (and so take -o/--output).
WRITERS = ('simulate', 'resim', 'plot', 'excite', 'identify', 'stability', 'recover')


def run(*args, cwd=None):
    """Run the linked executable with ``args``; return the CompletedProcess."""
    if not EXE.exists():
        pytest.skip('.venv/bin/leadscrew_sim exists after make setup')
    env = dict(os.environ, AMENT_PREFIX_PATH=str(REPO / '.venv'))
    return subprocess.run([str(EXE), *map(str, args)], cwd=cwd, env=env, capture_output=True,
                          text=True, timeout=300)


def options(help_text):
    """Return {option line: its help text} of the ``options:`` section of ``help_text``."""
    section = help_text.split('\noptions:\n', 1)[1]
    found, current = {}, None
    for line in section.splitlines():
        m = re.match(r'  (-\S.*?)(?:\s{2,}(\S.*))?$', line)
        if m:
            current = m.group(1)
            found[current] = m.group(2) or ''
        elif line.startswith('    ') and current is not None:
            found[current] = (found[current] + ' ' + line.strip()).strip()
    return found


def test_verbs_are_listed_with_summary_as_alias():
    res = run('--help')
    assert res.returncode == 0, res.stderr
    assert re.search(r'summary\s+alias of info', res.stdout)
    assert '--rate' not in res.stdout


@pytest.mark.parametrize('verb', [name for name, _ in VERBS])
def test_help_of_every_verb(verb):
    res = run(verb, '--help')
    assert res.returncode == 0, res.stderr
    opts = options(res.stdout)
    assert opts, res.stdout
    missing = [o for o, text in opts.items() if not text]
    assert not missing, f'{verb}: options without help: {missing}'
    flags = set(re.findall(r'(?<![\w-])(--?[a-z][\w-]*)', ' '.join(opts)))
    assert {'-q', '--quiet'} <= flags, f'{verb}: no -q/--quiet'
    if verb in WRITERS:
        assert '-o' in flags, f'{verb} writes a file: no -o'
    assert '--rate' not in flags and '--rate ' not in res.stdout, f'{verb} shows --rate'
    positionals = res.stdout.split('\npositional arguments:\n', 1)
    if len(positionals) == 2:
        for line in positionals[1].split('\n\n', 1)[0].splitlines():
            if re.match(r'  \S+$', line):
                pytest.fail(f'{verb}: positional {line.strip()} without help')


def test_rate_is_a_deprecated_alias(tmp_path):
    out = tmp_path / 'r.mcap'
    res = run('simulate', '--rate', 500, '--duration', 0.02, '--torque', 0.0, '-o', out, '-q')
    assert res.returncode == 0, res.stderr
    assert res.stderr.splitlines() == [
        'leadscrew_sim: warning: --rate is deprecated here; use --update-rate']
    assert 'at 500 Hz' in res.stdout


@pytest.mark.parametrize('argv, new', [
    (('excite', 'sweep', '--rate', 50, '--dry-run', 2), '--command-rate'),
    (('identify', '--rate', 'nan', 'missing.mcap'), '--step-rate'),
])
def test_rate_names_the_new_flag_in_each_verb(tmp_path, argv, new):
    res = run(*argv, cwd=tmp_path)
    assert f'--rate is deprecated here; use {new}' in res.stderr.splitlines()[0]
    if argv[0] == 'excite':
        assert res.returncode == 0 and 'at 50 Hz' in res.stdout, res.stderr


def test_set_suggests_the_nearest_names(tmp_path):
    res = run('simulate', '--set', 'backlsh=1e-4', '-o', tmp_path / 'x.mcap', '-q')
    assert res.returncode == 1
    assert "--set: unknown parameter 'backlsh' (did you mean backlash" in res.stderr
    assert 'mu_viscous' not in res.stderr
