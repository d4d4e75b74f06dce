"""The report page: the template file filled with the sections' blocks (no script, no network)."""
import html
import os
import string

#: The template beside this module (installed with the package).
TEMPLATE = os.path.join(os.path.dirname(__file__), 'report_template.html')


def _block(b):
    kind = b[0]
    if kind == 'p':
        return f'<p>{html.escape(b[1])}</p>'
    if kind == 'sentence':
        return f'<p class="sentence">{html.escape(b[1])}</p>'
    if kind == 'img':
        return f'<img src="{b[1]}" alt="{html.escape(b[2])}">'
    if kind == 'table':
        head = ''.join(f'<th>{html.escape(str(h))}</th>' for h in b[1])
        rows = ''.join('<tr>' + ''.join(f'<td>{html.escape(_cell(c))}</td>' for c in row)
                       + '</tr>' for row in b[2])
        return f'<table><tr>{head}</tr>{rows}</table>'
    if kind == 'cannot':
        if not b[1]:
            return ''
        items = ''.join(f'<li>{html.escape(x)}</li>' for x in b[1])
        return f'<p>What these data cannot determine:</p><ul class="cannot">{items}</ul>'
    raise ValueError(f'unknown block {kind!r}')


def _cell(c):
    if c is None:
        return 'not determined'
    if isinstance(c, float):
        return f'{c:.5g}'
    return str(c)


def render(title, subtitle, sections):
    """
    Return the page: ``sections`` is [(number, id, heading, blocks)].

    A block is ('p', text), ('sentence', text), ('img', data URI, alt text),
    ('table', header, rows) or ('cannot', [lines]).
    """
    with open(TEMPLATE) as fh:
        template = string.Template(fh.read())
    parts = []
    for number, sid, heading, blocks in sections:
        body = '\n'.join(_block(b) for b in blocks)
        parts.append(f'<section id="{sid}">\n<h2>{number}. {html.escape(heading)}</h2>\n'
                     f'{body}\n</section>')
    return template.substitute(title=html.escape(title), subtitle=html.escape(subtitle),
                               sections='\n'.join(parts))
