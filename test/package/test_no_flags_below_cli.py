"""
No flag below cli/: the run library names options by their keywords, the command line by flags.

Oracles: Python's own parser (``ast``) for every string constant (messages,
report texts, docstrings) of the modules outside ``cli/`` and ``ros/``,
searched for a command-line flag (``--set``, ``--command-topic``, ``-o``);
and the two faces of one error: the library's text, and the command line's
line on stderr, which keeps the flag.
"""
import ast
import re

from helpers import REPO
import pytest

PKG = REPO / 'leadscrew_sim'

#: A command-line flag in a text: ``--name`` or ``-o``, not inside a word, a longer dash
#: run or a backquoted literal.
FLAG = re.compile(r'(?<![\w\-`])(--[a-z][a-z0-9-]+|-o\b)')


def flags_in(source):
    """Return [(line, 'doc' or 'str', flag)] of the string constants of ``source``."""
    tree = ast.parse(source)
    docs = set()
    for node in ast.walk(tree):
        if isinstance(node, (ast.Module, ast.FunctionDef, ast.ClassDef, ast.AsyncFunctionDef)):
            first = node.body[0] if node.body else None
            if isinstance(first, ast.Expr) and isinstance(first.value, ast.Constant):
                docs.add(id(first.value))
    hits = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Constant) and isinstance(node.value, str):
            for m in FLAG.finditer(node.value):
                hits.append((node.lineno, 'doc' if id(node) in docs else 'str', m.group(1)))
    return hits


def test_the_scan_finds_a_flag():
    """The oracle can fail: flags in a message, an f-string and a docstring are found."""
    source = ('def f(x):\n'
              '    """Read --map."""\n'
              "    raise ValueError(f'--set {x}: bad; -o out')\n"
              "g = 'a--b ``--c`` co-ordinates in-out'\n")
    assert flags_in(source) == [(2, 'doc', '--map'), (3, 'str', '--set'), (3, 'str', '-o')]


def test_no_string_below_cli_names_a_flag():
    """No string constant outside cli/ and ros/ names a command-line flag."""
    found = []
    for path in sorted(PKG.rglob('*.py')):
        rel = path.relative_to(PKG).as_posix()
        if rel.startswith(('cli/', 'ros/')):
            continue
        found += [f'leadscrew_sim/{rel}:{line} ({kind}) {flag}'
                  for line, kind, flag in flags_in(path.read_text())]
    assert not found, 'flags named below cli/:\n' + '\n'.join(found)


def test_the_library_names_the_keyword():
    """A bad ``set`` item: the library's error names the keyword, never the flag."""
    from leadscrew_sim.offline.options import parse_sets, RunError
    with pytest.raises(RunError) as info:
        parse_sets(['abc'])
    text = str(info.value)
    assert "set 'abc'" in text and '--set' not in text, text
    assert text == "set 'abc': expected name=value"


def test_the_command_line_names_the_flag(tmp_path, capsys):
    """The same error from the command line: exit status 1, the flag on stderr."""
    from leadscrew_sim.cli.main import main
    status = main(['simulate', '--set', 'abc', '-q', '--duration', '0.01',
                   '-o', str(tmp_path / 'x.mcap')])
    err = capsys.readouterr().err
    assert status == 1
    assert err == "leadscrew_sim: error: --set 'abc': expected name=value\n", err


def test_a_verb_names_its_own_flag_for_a_keyword(tmp_path, capsys):
    """The step rate of identify: the option ``rate`` there, yet named ``--step-rate``."""
    from leadscrew_sim.cli.main import main
    from leadscrew_sim.offline.options import RunError
    run = tmp_path / 'run.mcap'
    assert main(['simulate', '-q', '--duration', '0.05', '-o', str(run)]) == 0
    capsys.readouterr()
    assert main(['identify', str(run), '--step-rate', '0', '-q']) == 1
    err = capsys.readouterr().err
    assert err == 'leadscrew_sim: error: --step-rate 0.0 Hz must lie in [1, 1e6]\n', err
    import leadscrew_sim as ls
    with pytest.raises(RunError) as info:
        ls.identify(ls.open_recording(run, ls.Mapping(step_rate=0.5)), fit=['mu_k'])
    assert 'step_rate' in str(info.value) and '--' not in str(info.value), str(info.value)
