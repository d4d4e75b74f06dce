"""
The public core and analysis APIs document every argument in numpydoc Parameters sections.

As python-control checks its own API:

A public function or method whose signature has an argument that its
docstring's Parameters section does not list fails here, naming both. Every
field of the parameter schemas has a unit and a description.
"""
import inspect
import re

import pytest

from leadscrew_sim import core
from leadscrew_sim.core import commands, delivery, drive_modes, fields, presets
from leadscrew_sim.core.engine import drive
from leadscrew_sim.core.settings import RunSettings
from leadscrew_sim.analysis import figures, linear, stability
from leadscrew_sim.analysis.excitation import profiles
from leadscrew_sim.analysis.identify import fit

#: The public core API: model construction, stepping, running, parameters.
API = [core.LeadScrewModel, core.ScrewParams, core.load_preset, presets.preset_path,
       presets.read_parameter_file, presets.physics_subset, fields.field,
       commands.CommandHold, RunSettings, delivery.StateDelivery, delivery.lost_samples,
       drive.command_rows, drive_modes.mode_code]

#: The public analysis API: identification, excitation profiles, figures, the drive's
#: linear design and the stability of steady sliding.
ANALYSIS_API = [fit.fit, fit.coordinates, fit.bounds, fit.typical_size, fit.FitResult,
                profiles.make_profile, profiles.static_breakaway, profiles.BreakawayRamp,
                profiles.SpeedSweep, profiles.Reversals, profiles.Iso230,
                figures.breakaway_torques, figures.stribeck_points, figures.axial_load,
                figures.efficiencies, figures.reversal_error, figures.derived_figures,
                figures.hold_series, linear.total_inertia, linear.design_gains,
                linear.closed_loop, linear.loop_response] + [
                    getattr(stability, name) for name in stability.__all__
                    if callable(getattr(stability, name))]


def documented_parameters(doc):
    """Return the names listed in the numpydoc Parameters section of ``doc``."""
    lines = inspect.cleandoc(doc or '').splitlines()
    names, inside = set(), False
    for i, line in enumerate(lines):
        if line.strip() == 'Parameters' and i + 1 < len(lines) and \
                set(lines[i + 1].strip()) == {'-'}:
            inside = True
            continue
        if inside:
            if i + 1 < len(lines) and lines[i + 1].strip() and \
                    set(lines[i + 1].strip()) == {'-'}:
                break                               # the next section starts
            m = re.match(r'^(\*{0,2}[A-Za-z_][\w, *]*?)\s*:', line)
            if m and not line.startswith(' '):
                names.update(n.strip() for n in m.group(1).split(','))
            elif re.match(r'^\*\*\w+\s*$', line):
                names.add(line.strip())
    return names


def signature_arguments(fn):
    """Return the argument names of ``fn`` as a docstring lists them (``**kw`` for kwargs)."""
    out = []
    for p in inspect.signature(fn).parameters.values():
        if p.name in ('self', 'cls'):
            continue
        if p.kind is p.VAR_KEYWORD:
            out.append('**' + p.name)
        elif p.kind is p.VAR_POSITIONAL:
            out.append('*' + p.name)
        else:
            out.append(p.name)
    return out


def public_callables():
    """Yield (label, function, docstring holding its Parameters) of the public API."""
    for obj in API + ANALYSIS_API:
        if inspect.isclass(obj):
            if '__init__' in vars(obj):
                yield obj.__name__, obj.__init__, obj.__doc__ or ''
            for name, member in vars(obj).items():
                if name.startswith('_') or not inspect.isfunction(member):
                    continue
                yield f'{obj.__name__}.{name}', member, member.__doc__
        else:
            yield obj.__name__, obj, obj.__doc__


CASES = list(public_callables())


@pytest.mark.parametrize('label,fn,doc', CASES, ids=[c[0] for c in CASES])
def test_every_argument_is_documented(label, fn, doc):
    args = signature_arguments(fn)
    assert doc, f'{label} has no docstring'
    if not args:
        return
    missing = [a for a in args if a not in documented_parameters(doc)]
    assert not missing, f'{label}: arguments {missing} missing from its Parameters section'


UNDOCUMENTED_B = """
    Do nothing.

    Parameters
    ----------
    a : float
        A length [m].
    **kw
        Anything.

    """


def test_the_checker_finds_an_undocumented_argument():
    def documented(a, b=1, **kw):
        pass
    documented.__doc__ = UNDOCUMENTED_B
    assert documented_parameters(documented.__doc__) == {'a', '**kw'}
    assert signature_arguments(documented) == ['a', 'b', '**kw']
    missing = [x for x in signature_arguments(documented)
               if x not in documented_parameters(documented.__doc__)]
    assert missing == ['b']


@pytest.mark.parametrize('schema', [core.ScrewParams, RunSettings])
def test_every_field_has_a_unit_and_a_description(schema):
    for name, (_typ, _default, md) in schema.field_info().items():
        assert md['unit'], f'{schema.__name__}.{name} has no unit'
        assert len(md['description']) > 10, f'{schema.__name__}.{name} has no description'
