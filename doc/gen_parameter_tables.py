#!/usr/bin/env python3
"""
Print the Markdown parameter tables of the package, generated from the field metadata.

Every physical parameter (:class:`leadscrew_sim.core.params.ScrewParams`) and
every run setting (:class:`leadscrew_sim.core.settings.RunSettings`) carries
its unit, description, range and default in its dataclass field. This script
turns them into the tables of ``doc/model.md`` (between the marker comments
``<!-- parameters:begin -->`` and ``<!-- parameters:end -->``) and
``doc/interfaces.md`` (``<!-- run-settings:begin -->`` / ``<!-- run-settings:end -->``).

Usage::

    python doc/gen_parameter_tables.py          # both tables, for doc/model.md
    python doc/gen_parameter_tables.py run      # the run settings only, for doc/interfaces.md
"""
import sys

from leadscrew_sim.core.params import ScrewParams
from leadscrew_sim.core.settings import RunSettings

PHYSICS_TITLE = '### Physical parameters (`ScrewParams`)'
RUN_TITLE = '### Run settings (`RunSettings`)'


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
        lines.append(f'| `{name}` | {unit} | {default_text(default)} | '
                     f'{range_text(typ, md)} | {meaning} |')
    return lines


def main(argv=None):
    """Print the tables: both (no argument) or the run settings only (``run``)."""
    argv = sys.argv[1:] if argv is None else argv
    if argv not in ([], ['run']):
        print('usage: gen_parameter_tables.py [run]', file=sys.stderr)
        return 2
    lines = []
    if not argv:
        lines += [PHYSICS_TITLE, ''] + table(ScrewParams) + ['']
    lines += [RUN_TITLE, ''] + table(RunSettings)
    print('\n'.join(lines))
    return 0


if __name__ == '__main__':
    sys.exit(main())
