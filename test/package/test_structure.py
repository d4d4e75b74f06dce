"""
The package's structure: no import circle, no flags below cli/, one root of every error.

Oracles: Python's own parser (``ast``) for the imports, every one of them,
those inside functions included (a lazy import still ties two modules
together), with Tarjan's strongly connected components for the circles; and
the classes themselves, imported, for the errors.
"""
import ast
import importlib
import inspect
import sys

from helpers import REPO
import pytest

PKG = REPO / 'leadscrew_sim'


def modules():
    """Return {dotted module name: path} of the package."""
    out = {}
    for path in PKG.rglob('*.py'):
        parts = list(path.relative_to(REPO).with_suffix('').parts)
        if parts[-1] == '__init__':
            parts = parts[:-1]
        out['.'.join(parts)] = path
    return out


def import_graph(mods):
    """Return {module: set of the package's modules it imports}, at any depth of its code."""
    graph = {}
    for name, path in mods.items():
        package = name if path.name == '__init__.py' else name.rpartition('.')[0]
        targets = set()
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.Import):
                targets.update(a.name for a in node.names)
            elif isinstance(node, ast.ImportFrom):
                base = package.split('.')
                if node.level:
                    base = base[:len(base) - (node.level - 1)]
                    src = '.'.join(base + ([node.module] if node.module else []))
                else:
                    src = node.module or ''
                subs = [f'{src}.{a.name}' for a in node.names if f'{src}.{a.name}' in mods]
                targets.update(subs or [src])
        graph[name] = {t for t in targets if t in mods and t != name}
    return graph


def circles(graph):
    """Return the strongly connected components of more than one module (Tarjan)."""
    index, low, on, stack, out = {}, {}, set(), [], []
    counter = [0]

    def visit(v):
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        for w in graph[v]:
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(sorted(comp))
    limit = sys.getrecursionlimit()
    sys.setrecursionlimit(max(limit, 10000))
    try:
        for v in graph:
            if v not in index:
                visit(v)
    finally:
        sys.setrecursionlimit(limit)
    return out


def test_the_circle_finder_finds_a_circle():
    """The oracle can fail: a two-module circle and a three-module one are found."""
    graph = {'a': {'b'}, 'b': {'a'}, 'c': {'d'}, 'd': {'e'}, 'e': {'c'}, 'f': {'a'}}
    assert sorted(circles(graph)) == [['a', 'b'], ['c', 'd', 'e']]


def test_the_package_has_no_import_circle():
    """No module imports, however lazily, a module that imports it back (directly or not)."""
    found = circles(import_graph(modules()))
    assert not found, f'import circles: {found}'


def test_no_module_below_cli_parses_flags():
    """Keep argparse in cli/: no module outside it imports argparse, at any depth."""
    found = []
    for name, path in modules().items():
        if name.startswith('leadscrew_sim.cli'):
            continue
        for node in ast.walk(ast.parse(path.read_text())):
            names = ([a.name for a in node.names] if isinstance(node, ast.Import) else
                     [node.module] if isinstance(node, ast.ImportFrom) else [])
            if any(n and n.split('.')[0] == 'argparse' for n in names):
                found.append(name)
    assert not found, f'argparse imported below cli/: {sorted(set(found))}'


def test_every_error_derives_from_leadscrew_error():
    """Each exception class the package defines is a LeadscrewError (private ones aside)."""
    from leadscrew_sim import LeadscrewError
    missing = []
    for name in sorted(modules()):
        if name.endswith('__main__'):       # runs the command line when imported
            continue
        try:
            mod = importlib.import_module(name)
        except ImportError as exc:           # an optional dependency (tested elsewhere)
            pytest.fail(f'{name} does not import: {exc}')
        for cname, cls in inspect.getmembers(mod, inspect.isclass):
            if (cls.__module__ == name and issubclass(cls, BaseException)
                    and not cname.startswith('_') and not issubclass(cls, LeadscrewError)):
                missing.append(f'{name}.{cname}')
    assert not missing, f'not LeadscrewError subclasses: {missing}'


def test_a_bad_value_names_the_parameter_value_and_range():
    """A parameter set with mu_k -1 raises a LeadscrewError naming mu_k, -1 and the range."""
    from leadscrew_sim import LeadscrewError, ScrewParams
    with pytest.raises(LeadscrewError) as info:
        ScrewParams.from_dict({'mu_k': -1})
    text = str(info.value)
    assert 'mu_k' in text and '-1' in text and '[0.0, 2.0]' in text, text
