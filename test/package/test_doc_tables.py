"""
The generated parameter tables of the docs equal the generator's current output.

``doc/gen_parameter_tables.py`` turns the field metadata of ScrewParams and
RunSettings into the Markdown tables between the marker lines
``<!-- parameters:begin/end -->`` of doc/model.md and
``<!-- run-settings:begin/end -->`` of doc/interfaces.md. A new parameter, or
a changed unit, default, range or description, without regenerating the docs
fails here. Oracles: the generator's output (for the docs), and the field
names of the schemas (for the generator: every field has a row).
"""
import difflib
import importlib.util

from helpers import REPO
import pytest

from leadscrew_sim.core.params import ScrewParams
from leadscrew_sim.core.settings import RunSettings

GENERATOR = REPO / 'doc' / 'gen_parameter_tables.py'
FIX = 'regenerate them: python doc/gen_parameter_tables.py --write'


def load_generator():
    """Import doc/gen_parameter_tables.py (the doc directory is no package)."""
    spec = importlib.util.spec_from_file_location('gen_parameter_tables', GENERATOR)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


gen = load_generator()


def stale_lines(text, marker, argv):
    """Return the unified diff of the block of ``marker`` in text against the output."""
    have = gen.block(text, marker)
    want = gen.render(argv)
    return list(difflib.unified_diff(have.splitlines(), want.splitlines(), 'doc', 'generator',
                                     n=0, lineterm=''))


@pytest.mark.parametrize('doc, marker, argv', gen.SECTIONS, ids=[s[0] for s in gen.SECTIONS])
def test_block_equals_the_generator_output(doc, marker, argv):
    text = (REPO / doc).read_text()
    diff = stale_lines(text, marker, argv)
    assert not diff, f'{doc}: the {marker} tables are stale; {FIX}\n' + '\n'.join(diff)


def test_the_sections_are_the_two_docs():
    assert [(d, m, a) for d, m, a in gen.SECTIONS] == [
        ('doc/model.md', 'parameters', []), ('doc/interfaces.md', 'run-settings', ['run'])]


def row_names(output):
    """Return the parameter names of the table rows of an output, in order."""
    return [line.split('`')[1] for line in output.splitlines() if line.startswith('| `')]


def test_every_field_has_one_row():
    assert row_names(gen.render([])) == (list(ScrewParams.parameter_names())
                                         + list(RunSettings.names()))
    assert row_names(gen.render(['run'])) == list(RunSettings.names())


def test_main_prints_render(capsys):
    for argv in ([], ['run']):
        assert gen.main(argv) == 0
        assert capsys.readouterr().out == gen.render(argv)
    assert gen.main(['bogus']) == 2


def test_a_changed_row_fails():
    """The check can fail: an edited, a missing and an extra row are all reported."""
    text = (REPO / 'doc' / 'interfaces.md').read_text()
    row = next(line for line in gen.block(text, 'run-settings').splitlines()
               if line.startswith('| `command_timeout`'))
    edited = text.replace(row, row.replace('`0.5`', '`0.25`'), 1)
    assert any(line.startswith('-| `command_timeout`')
               for line in stale_lines(edited, 'run-settings', ['run']))
    assert stale_lines(text.replace(row + '\n', '', 1), 'run-settings', ['run'])
    extra = text.replace(row, row + '\n| `new_setting` | - | `0` | - | new |', 1)
    assert stale_lines(extra, 'run-settings', ['run'])


def test_a_new_field_without_regenerating_fails(monkeypatch):
    """A field the docs do not have yet (a schema with one more row) makes the docs stale."""
    real = RunSettings.field_info()
    info = dict(real, zz_new_setting=(float, 1.0, dict(real['real_time_factor'][2])))
    monkeypatch.setattr(gen, 'RunSettings', type('Grown', (), {
        'field_info': staticmethod(lambda: info)}))
    for doc, marker, argv in gen.SECTIONS:
        diff = stale_lines((REPO / doc).read_text(), marker, argv)
        assert any(line.startswith('+| `zz_new_setting`') for line in diff), doc


def test_markers_must_be_there_once():
    with pytest.raises(ValueError):
        gen.block('no markers', 'parameters')
    one = '<!-- parameters:begin -->\nx\n<!-- parameters:end -->\n'
    assert gen.block(one, 'parameters') == 'x\n'
    with pytest.raises(ValueError):
        gen.block(one + one, 'parameters')
    with pytest.raises(ValueError):
        gen.block('<!-- parameters:end -->\n<!-- parameters:begin -->\n', 'parameters')
    assert gen.replace_block(one, 'parameters', 'y\n') == one.replace('x', 'y')
