"""
Parameter fields with units and ranges: one schema for the physics and the run settings.

A field is a dataclass field whose metadata holds its unit, description,
range, choices and whether it is read-only at run time. :func:`coerce`
turns a value from a file, the command line or ROS into the field's type;
:func:`check` enforces its range. Both raise :class:`ParameterError`,
whose message names the parameter, the value and the allowed range.
"""
import dataclasses
import inspect
import math
from .errors import LeadscrewError


#: Field name prefixes that stand for a parameter namespace: the field ``fault_jam`` is
#: the parameter ``fault.jam`` in ROS, in parameter files and in messages.
NAMESPACES = ('fault',)


def public_name(name):
    """Return the parameter name of a field name (``fault_jam`` -> ``fault.jam``)."""
    for ns in NAMESPACES:
        if name.startswith(ns + '_'):
            return f'{ns}.{name[len(ns) + 1:]}'
    return name


def field_name(name):
    """Return the field name of a parameter name (``fault.jam`` -> ``fault_jam``)."""
    for ns in NAMESPACES:
        if name.startswith(ns + '.'):
            return f'{ns}_{name[len(ns) + 1:]}'
    return name


def flatten(values):
    """Return a mapping by field name: ``{'fault': {'jam': v}}`` or ``fault.jam`` -> fault_jam."""
    out = {}
    for k, v in values.items():
        if k in NAMESPACES and isinstance(v, dict):
            out.update({f'{k}_{sub}': x for sub, x in v.items()})
        else:
            out[field_name(k)] = v
    return out


class ParameterError(LeadscrewError, ValueError):
    """An invalid parameter value or an inconsistent parameter set."""

    def __init__(self, name, message):
        """Keep the parameter name; the message reads ``parameter 'name': message``."""
        name = public_name(name)
        super().__init__(f"parameter '{name}': {message}")
        self.name = name


def field(default, unit, desc, lo=None, hi=None, lo_open=False, choices=None,
          read_only=False):
    """
    Return a dataclass field with its schema in the metadata.

    Parameters
    ----------
    default : bool, int, float or str
        Default value.
    unit : str
        SI unit, ``'-'`` for dimensionless and non-numeric values.
    desc : str
        One-line description.
    lo, hi : float, optional
        Allowed range (closed; ``lo_open`` makes the lower bound open).
    lo_open : bool
        Exclude ``lo`` itself.
    choices : tuple of str, optional
        The allowed values of a string field.
    read_only : bool
        The value cannot change while a node runs.

    """
    return dataclasses.field(default=default, metadata=dict(
        unit=unit, description=desc, lo=lo, hi=hi, lo_open=lo_open,
        choices=choices, read_only=read_only))


def _with_unit(value, unit):
    return f'{value!r}' if unit in ('-', '') else f'{value!r} {unit}'


def coerce(f, value):
    """
    Return ``value`` as the type of field ``f``.

    Booleans and strings must have their type; an integer field takes an
    integral float; a floating-point field takes an integer (``0`` for
    ``0.0``). Raises ParameterError otherwise.
    """
    md = f.metadata
    if f.type in ('bool', bool):
        if isinstance(value, bool):
            return value
        raise ParameterError(f.name, f'{value!r} is not a boolean (true/false)')
    if f.type in ('str', str):
        if isinstance(value, str):
            return value
        allowed = f'; allowed: {", ".join(md["choices"])}' if md.get('choices') else ''
        raise ParameterError(f.name, f'{value!r} is not a string{allowed}')
    if f.type in ('int', int):
        if isinstance(value, bool) or not (
                isinstance(value, int) or (isinstance(value, float) and value.is_integer())):
            raise ParameterError(f.name, f'{value!r} is not an integer')
        return int(value)
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        unit = '' if md['unit'] in ('-', '') else f' [{md["unit"]}]'
        raise ParameterError(f.name, f'{value!r} is not a number{unit}')
    return float(value)


def check(f, value):
    """Raise ParameterError unless ``value`` is finite and within the range of field ``f``."""
    md = f.metadata
    if md.get('choices'):
        if value not in md['choices']:
            raise ParameterError(f.name, f'{value!r} is not one of {", ".join(md["choices"])}')
        return
    if isinstance(value, bool) or f.type in ('bool', bool):
        if not isinstance(value, bool):
            raise ParameterError(f.name, f'{value!r} is not a boolean')
        return
    if isinstance(value, str) or f.type in ('str', str):
        if not isinstance(value, str):
            raise ParameterError(f.name, f'{value!r} is not a string')
        return
    if not isinstance(value, (int, float)) or not math.isfinite(value):
        unit = '' if md['unit'] in ('-', '') else f' [{md["unit"]}]'
        raise ParameterError(f.name, f'{value!r} is not a finite number{unit}')
    lo, hi = md['lo'], md['hi']
    bad_lo = lo is not None and (value <= lo if md['lo_open'] else value < lo)
    if bad_lo or (hi is not None and value > hi):
        bracket = '(' if md['lo_open'] else '['
        raise ParameterError(f.name, f'{_with_unit(value, md["unit"])} is outside the allowed '
                             f'range {bracket}{lo}, {hi}]')


def from_text(f, text):
    """Return the value of field ``f`` from its ``str()`` (as metadata records store it)."""
    if f.type in ('bool', bool):
        if text in ('True', 'False'):
            return text == 'True'
        raise ParameterError(f.name, f'{text!r} is not True or False')
    if f.type in ('int', int):
        try:
            return int(text)
        except ValueError:
            raise ParameterError(f.name, f'{text!r} is not an integer') from None
    if f.type in ('float', float):
        try:
            return float(text)
        except ValueError:
            raise ParameterError(f.name, f'{text!r} is not a number') from None
    return text


def document(cls):
    """
    Append a numpydoc Parameters section, built from the field metadata, to a schema class.

    Parameters
    ----------
    cls : type
        A dataclass of :func:`field` fields; returned with its docstring extended.

    """
    lines = ['', 'Parameters', '----------']
    for f in dataclasses.fields(cls):
        md = f.metadata
        typ = getattr(f.type, '__name__', str(f.type))
        lines.append(f'{f.name} : {typ}')
        rng = ''
        if md.get('choices'):
            rng = f' One of: {", ".join(md["choices"])}.'
        elif md.get('lo') is not None:
            rng = f' Range {"(" if md["lo_open"] else "["}{md["lo"]}, {md["hi"]}].'
        unit = '' if md['unit'] in ('-', '') else f' [{md["unit"]}]'
        ro = ' Read-only at run time.' if md.get('read_only') else ''
        lines.append(f'    {md["description"]}{unit}. Default {f.default!r}.{rng}{ro}')
    cls.__doc__ = inspect.cleandoc(cls.__doc__ or '') + '\n' + '\n'.join(lines) + '\n'
    return cls


class Schema:
    """Mix-in of a frozen dataclass of fields: validated construction from mappings."""

    def __post_init__(self):
        """Check every field, then the set as a whole."""
        for f in dataclasses.fields(self):
            check(f, getattr(self, f.name))
        self._check_consistency()

    def _check_consistency(self):
        """Check rules between fields (none by default)."""

    def replace(self, **changes):
        """Return a validated copy with some fields changed."""
        return dataclasses.replace(self, **changes)

    def to_dict(self):
        """Return a plain dict of all fields."""
        return dataclasses.asdict(self)

    @classmethod
    def from_dict(cls, values, base=None):
        """
        Build from a mapping (coerced per field) over ``base``; unknown keys raise.

        Keys are field or parameter names (``fault_jam`` or ``fault.jam``), and
        a namespace may be a nested mapping (``{'fault': {'jam': True}}``).
        """
        known = {f.name: f for f in dataclasses.fields(cls)}
        values = flatten(values)
        for k in values:
            if k not in known:
                names = ', '.join(sorted(public_name(n) for n in known))
                raise ParameterError(k, f'unknown parameter (known: {names})')
        coerced = {k: coerce(known[k], v) for k, v in values.items()}
        base = base if base is not None else cls()
        return dataclasses.replace(base, **coerced)

    @classmethod
    def from_text(cls, values, base=None):
        """Build from ``{name: str(value)}`` (a metadata record); other keys are ignored."""
        known = {f.name: f for f in dataclasses.fields(cls)}
        values = {field_name(k): v for k, v in values.items()}
        return cls.from_dict({k: from_text(known[k], v) for k, v in values.items()
                              if k in known}, base=base)

    @classmethod
    def field_info(cls):
        """Return {name: (type, default, metadata)} for descriptors and docs."""
        return {f.name: (f.type, f.default, dict(f.metadata)) for f in dataclasses.fields(cls)}

    @classmethod
    def names(cls):
        """Return the field names in declaration order."""
        return tuple(f.name for f in dataclasses.fields(cls))

    @classmethod
    def parameter_names(cls):
        """Return the parameter names (``fault.jam`` for ``fault_jam``) in declaration order."""
        return tuple(public_name(f.name) for f in dataclasses.fields(cls))
