#!/usr/bin/env python3
"""
Print the Markdown parameter tables of the package, generated from the field metadata.

Every physical parameter (:class:`leadscrew_sim.core.params.ScrewParams`) and
every run setting (:class:`leadscrew_sim.core.settings.RunSettings`) carries
its unit, description, range and default in its dataclass field. This script
turns them into the tables of ``doc/model.md`` (between the marker comments
``<!-- parameters:begin -->`` and ``<!-- parameters:end -->``) and
``doc/interfaces.md`` (``<!-- run-settings:begin -->`` / ``<!-- run-settings:end -->``).
``test/package/test_doc_tables.py`` checks that both blocks equal the output.

Usage::

    python doc/gen_parameter_tables.py          # both tables, for doc/model.md
    python doc/gen_parameter_tables.py run      # the run settings only, for doc/interfaces.md
    python doc/gen_parameter_tables.py --write  # replace both blocks in the docs
"""
from pathlib import Path
import sys

from leadscrew_sim.core.fields import public_name
from leadscrew_sim.core.params import ScrewParams
from leadscrew_sim.core.settings import RunSettings

PHYSICS_TITLE = '### Physical parameters (`ScrewParams`)'
RUN_TITLE = '### Run settings (`RunSettings`)'

#: The generated blocks: (document relative to the repository, marker, argv of the output).
SECTIONS = (('doc/model.md', 'parameters', []), ('doc/interfaces.md', 'run-settings', ['run']))

#: The repository root (this file is doc/gen_parameter_tables.py).
REPO = Path(__file__).resolve().parents[1]


def number(value):
    """Return a short exact text of a number: 6 significant digits when that is exact."""
    if isinstance(value, bool):
        return 'true' if value else 'false'
    if isinstance(value, int):
        return str(value)
    short = f'{value:.6g}'
    return short if float(short) == value else repr(value)


def default_text(value):
    """Return the Markdown text of a default value."""
    if isinstance(value, str):
        return f"`'{value}'`"
    return f'`{number(value)}`'


def range_text(typ, md):
    """Return the allowed values of a field from its metadata."""
    if md.get('choices'):
        return ', '.join(f'`{c}`' for c in md['choices'])
    if typ in ('bool', bool):
        return '`true`, `false`'
    if md.get('lo') is None and md.get('hi') is None:
        return '-'
    lo = '-inf' if md.get('lo') is None else number(md['lo'])
    hi = 'inf' if md.get('hi') is None else number(md['hi'])
    return f'{"(" if md.get("lo_open") else "["}{lo}, {hi}]'


def table(schema):
    """Return the lines of the Markdown table of one schema class."""
    lines = ['| name | unit | default | range | meaning |', '|---|---|---|---|---|']
    for name, (typ, default, md) in schema.field_info().items():
        meaning = md['description'].replace('|', '\\|')
        if md.get('read_only'):
            meaning += ' (read-only at run time)'
        unit = md['unit']
        lines.append(f'| `{public_name(name)}` | {unit} | {default_text(default)} | '
                     f'{range_text(typ, md)} | {meaning} |')
    return lines


def render(argv):
    """Return the output for ``argv`` ([] or ['run']), ending with a newline, as printed."""
    lines = []
    if not argv:
        lines += [PHYSICS_TITLE, ''] + table(ScrewParams) + ['']
    lines += [RUN_TITLE, ''] + table(RunSettings)
    return '\n'.join(lines) + '\n'


def _span(text, marker):
    """Return (start, end) of the text between the marker lines of ``marker`` in text."""
    begin, end = f'<!-- {marker}:begin -->\n', f'<!-- {marker}:end -->'
    if text.count(begin) != 1 or text.count(end) != 1:
        raise ValueError(f'expected one line {begin.strip()} and one {end}')
    start, stop = text.index(begin) + len(begin), text.index(end)
    if stop < start or text[stop - 1] != '\n':
        raise ValueError(f'{end} must start a line after {begin.strip()}')
    return start, stop


def block(text, marker):
    """Return the text between the lines ``<!-- marker:begin -->`` and ``<!-- marker:end -->``."""
    start, stop = _span(text, marker)
    return text[start:stop]


def replace_block(text, marker, content):
    """Return text with the block of ``marker`` replaced by ``content``."""
    start, stop = _span(text, marker)
    return text[:start] + content + text[stop:]


def write_docs(repo=REPO):
    """Replace every generated block of the docs with the current output; return the changed."""
    changed = []
    for doc, marker, argv in SECTIONS:
        path = Path(repo) / doc
        text = path.read_text()
        new = replace_block(text, marker, render(argv))
        if new != text:
            path.write_text(new)
            changed.append(doc)
    return changed


def main(argv=None):
    """Print the tables: both (no argument) or the run settings only (``run``); or ``--write``."""
    argv = sys.argv[1:] if argv is None else argv
    if argv == ['--write']:
        for doc in write_docs():
            print(f'updated {doc}')
        return 0
    if argv not in ([], ['run']):
        print('usage: gen_parameter_tables.py [run | --write]', file=sys.stderr)
        return 2
    sys.stdout.write(render(argv))
    return 0


if __name__ == '__main__':
    sys.exit(main())
