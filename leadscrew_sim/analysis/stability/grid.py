"""
Grids of operating points and the rows of the stability table (interfaces.md, Analysis v3).

An axis is ``NAME=START:STOP:N[:log]``: N >= 2 values from START to STOP,
evenly or geometrically spaced; NAME is ``speed`` or a numeric ScrewParams
field (an integer field takes integral values only). At most MAX_AXES axes;
the cases are their product, the first axis varying slowest. :func:`run_case`
turns one case into one row: a case the model refuses, or that goes
non-finite, is a row with its reason in ``error``, never an exception.
"""
import dataclasses
import difflib
import itertools
import math

import numpy as np

from ...core.faults import SimulationFault
from ...core.params import ParameterError, ScrewParams
from .linear import linear_stability
from .nonlinear import nonlinear_stability

__all__ = ['case_params', 'COLUMNS', 'expand', 'METHODS', 'parse_axis', 'run_case']

MAX_AXES = 3
#: The result columns of a row, after the swept names.
COLUMNS = ('growth_rate', 'frequency', 'mechanism', 'effective_inertia', 'verdict',
           'amplitude_small', 'amplitude_large', 'stick_fraction', 'period', 'error')
#: The methods: the linear analysis, the nonlinear runs, or both.
METHODS = ('linear', 'nonlinear', 'both')
_NUMERIC = {f.name: f for f in dataclasses.fields(ScrewParams)
            if f.type in (int, float) and not f.metadata.get('read_only', False)
            or f.name in ('major_diameter', 'pitch', 'pitch_diameter', 'starts')}


def _number(name, text):
    try:
        value = float(text)
    except ValueError:
        raise ParameterError(name, f'{text!r} is not a number') from None
    if not math.isfinite(value):
        raise ParameterError(name, f'{text!r} is not finite')
    return value


def parse_axis(text, base):
    """
    Parse ``NAME=START:STOP:N[:log]`` into (name, values), each value checked against its range.

    Parameters
    ----------
    text : str
        The axis.
    base : ScrewParams
        The parameters the values replace (for the range checks).

    Raises
    ------
    ParameterError
        Naming the axis: an unknown name, a bad number, N < 2, a log axis
        through zero, or a value outside the parameter's range.

    """
    name, sep, spec = text.partition('=')
    name = name.strip()
    if not sep:
        raise ParameterError('grid', f'{text!r} is not NAME=START:STOP:N[:log]')
    if name != 'speed' and name not in _NUMERIC:
        close = difflib.get_close_matches(name, ('speed',) + tuple(_NUMERIC), n=3)
        hint = f' (did you mean {" or ".join(close)}?)' if close else ''
        raise ParameterError('grid', f'{name!r} is not speed or a numeric model parameter'
                             f'{hint}')
    parts = spec.split(':')
    if len(parts) not in (3, 4) or (len(parts) == 4 and parts[3] != 'log'):
        raise ParameterError('grid', f'{text!r} is not NAME=START:STOP:N[:log]')
    start, stop = _number(name, parts[0]), _number(name, parts[1])
    try:
        n = int(parts[2])
    except ValueError:
        raise ParameterError('grid', f'N {parts[2]!r} of {name} is not an integer') from None
    if n < 2:
        raise ParameterError('grid', f'N {n} of {name} is below the allowed minimum 2')
    if len(parts) == 4:
        if start * stop <= 0.0:
            raise ParameterError(name, f'log axis {start!r}:{stop!r} must not reach or cross 0')
        values = np.geomspace(start, stop, n)
    else:
        values = np.linspace(start, stop, n)
    values = [float(v) for v in values]
    if name == 'speed':
        if any(v == 0.0 for v in values):
            raise ParameterError('speed', f'the axis {start!r}:{stop!r}:{n} passes through 0 m/s '
                                 '(nonzero speeds only)')
    else:
        if _NUMERIC[name].type is int:
            if any(v != round(v) for v in values):
                raise ParameterError(name, f'takes integers; the axis {start!r}:{stop!r}:{n} '
                                     'gives fractions')
            values = [int(round(v)) for v in values]
        for v in (values[0], values[-1]):
            dataclasses.replace(base, **{name: v})      # range check
    return name, values


def expand(axes):
    """
    Return the cases of the axes' product, each a dict name -> value.

    Parameters
    ----------
    axes : list of (str, list)
        The parsed axes (at most MAX_AXES, names distinct).

    """
    if len(axes) > MAX_AXES:
        raise ParameterError('grid', f'{len(axes)} axes given; at most {MAX_AXES}')
    names = [a[0] for a in axes]
    if len(set(names)) != len(names):
        raise ParameterError('grid', f'an axis is repeated: {", ".join(names)}')
    return [dict(zip(names, combo)) for combo in itertools.product(*(a[1] for a in axes))]


def case_params(base, case, cache=None):
    """
    Return (params, speed override or None) of one case.

    Parameters
    ----------
    base : ScrewParams
        The base parameters.
    case : dict
        Swept name -> value.
    cache : dict, optional
        Parameters already built for this base, by their swept values: the
        cases of a batch that differ in speed only share one (validated) set.

    """
    fields = {k: v for k, v in case.items() if k != 'speed'}
    if not fields:
        return base, case.get('speed')
    key = tuple(sorted(fields.items()))
    params = cache.get(key) if cache is not None else None
    if params is None:
        params = dataclasses.replace(base, **fields)
        if cache is not None:
            cache[key] = params
    return params, case.get('speed')


def run_case(base, case, speed, drive='velocity', method='both', duration=2.0, cache=None):
    """
    Return the row of one case: the swept values, then COLUMNS.

    Parameters
    ----------
    base : ScrewParams
        The base parameters.
    case : dict
        Swept name -> value.
    speed : float
        Nut speed [m/s] unless ``speed`` is swept.
    drive : str
        'velocity' or 'ideal'.
    method : str
        One of METHODS.
    duration : float
        Length of each nonlinear run [s].
    cache : dict, optional
        Shared parameter sets and models of the batch (see :func:`case_params`
        and :func:`.nonlinear.nonlinear_stability`).

    """
    row = dict(case)
    row.update({c: math.nan for c in COLUMNS})
    row.update(mechanism='', verdict='', error='')
    try:
        params, v = case_params(base, case, cache)
        v = speed if v is None else v
        if method in ('linear', 'both'):
            lin = linear_stability(params, v, drive)
            row.update({k: lin[k] for k in ('growth_rate', 'frequency', 'mechanism',
                                            'effective_inertia')})
        if method in ('nonlinear', 'both'):
            models = cache.setdefault('models', {}) if cache is not None else None
            row.update(nonlinear_stability(params, v, drive, duration, models=models))
    except (ValueError, SimulationFault, ArithmeticError, np.linalg.LinAlgError) as exc:
        row['error'] = ' '.join(str(exc).split())
    return row
