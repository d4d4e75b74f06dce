"""
The stability table of a grid: the rows, their CSV, the printed summary.

:func:`stability_table` is the library call of the ``stability`` verb: it
parses the axes, runs the cases (:mod:`.executors`), writes the CSV
(interfaces.md, Analysis v3: the swept names, then grid.COLUMNS) and, if
asked, the map (:mod:`.plot`), and returns the rows with a summary: the
linear boundary along each axis (where growth_rate changes sign, linearly
interpolated between neighbouring cases) and the worst case. An interrupted
run writes the finished rows; the rest carry ``error`` INTERRUPTED.
"""
import csv
import math

from ...core.params import ParameterError
from .executors import run_cases
from .grid import COLUMNS, expand, METHODS, parse_axis
from .operating_point import DRIVES

__all__ = ['boundaries', 'INTERRUPTED', 'stability_table', 'write_csv']

INTERRUPTED = 'not run: interrupted'   #: error of the cases an interrupt left out


def write_csv(path, names, rows):
    """
    Write the rows to a CSV file: the swept names, then grid.COLUMNS (floats as repr).

    Parameters
    ----------
    path : str or pathlib.Path
        The file.
    names : list of str
        The swept names.
    rows : list of dict
        The rows.

    """
    cols = list(names) + list(COLUMNS)
    with open(path, 'w', newline='') as f:
        w = csv.writer(f)
        w.writerow(cols)
        for r in rows:
            w.writerow([repr(r[c]) if isinstance(r[c], float) else r[c] for c in cols])


def _along(axes):
    """Yield (name, stride, size) of each axis: the neighbour of case i along it is i + stride."""
    sizes = [len(a[1]) for a in axes]
    for k, (name, _values) in enumerate(axes):
        yield name, math.prod(sizes[k + 1:]), sizes[k]


def boundaries(axes, rows):
    """
    Return, per axis name, the values where growth_rate changes sign along that axis.

    Parameters
    ----------
    axes : list of (str, list)
        The parsed axes.
    rows : list of dict
        The rows in case order.

    """
    out = {}
    for name, stride, size in _along(axes):
        found = []
        for i, r in enumerate(rows):
            if (i // stride) % size == size - 1:
                continue
            a, b = r, rows[i + stride]
            ga, gb = a['growth_rate'], b['growth_rate']
            if ga * gb < 0.0:      # False for NaN
                va, vb = a[name], b[name]
                found.append(va + (vb - va) * ga / (ga - gb))
        out[name] = found
    return out


def bistable_ranges(axes, rows):
    """
    Return, per axis name, the (first, last) values of each run of bistable cases along it.

    Along an axis, with the other axes fixed, consecutive cases whose nonlinear
    verdict is ``bistable`` form one range (a case on its own: first = last).
    The range's ends are the grid's values: the true ends lie between them and
    their neighbours.

    Parameters
    ----------
    axes : list of (str, list)
        The parsed axes.
    rows : list of dict
        The rows in case order.

    """
    out = {}
    for name, stride, size in _along(axes):
        found = []
        for i, r in enumerate(rows):
            first = (i // stride) % size == 0
            if r['verdict'] == 'bistable' and (first or rows[i - stride]['verdict'] != 'bistable'):
                j = i
                while ((j // stride) % size < size - 1
                       and rows[j + stride]['verdict'] == 'bistable'):
                    j += stride
                found.append((r[name], rows[j][name]))
        out[name] = found
    return out


def _worst(rows):
    ok = [r for r in rows if not r['error']]
    if not ok:
        return None
    lin = [r for r in ok if not math.isnan(r['growth_rate'])]
    if lin:
        return max(lin, key=lambda r: r['growth_rate'])
    return max(ok, key=lambda r: r['amplitude_large'])


def stability_table(base, grid=(), speed=None, drive='velocity', method='both', duration=2.0,
                    workers=None, scheduler=None, csv_path=None, plot_path=None,
                    progress=False):
    """
    Run the stability analysis over a grid and return its rows and summary.

    Parameters
    ----------
    base : ScrewParams
        The base parameters.
    grid : sequence of str
        Axes ``NAME=START:STOP:N[:log]`` (at most 3); none: the one case.
    speed : float, optional
        Nut speed [m/s] (nonzero), required unless ``speed`` is an axis.
    drive : str
        'velocity' or 'ideal'.
    method : str
        'linear', 'nonlinear' or 'both'.
    duration : float
        Length of each nonlinear run [s].
    workers : int, optional
        Local worker processes (default: the cores).
    scheduler : str, optional
        Dask scheduler address.
    csv_path, plot_path : str, optional
        Where to write the CSV and the PNG map.
    progress : bool
        Progress bar on stderr (if a terminal).

    Returns
    -------
    dict
        names (swept), rows, complete (bool), boundaries (name -> values where the
        linear growth rate changes sign), bistable (name -> (first, last) values of
        each run of bistable cases), worst (row or None).

    """
    if drive not in DRIVES:
        raise ParameterError('drive', f'{drive!r} is not one of {", ".join(DRIVES)}')
    if method not in METHODS:
        raise ParameterError('method', f'{method!r} is not one of {", ".join(METHODS)}')
    if not (duration > 0.0 and math.isfinite(duration)):
        raise ParameterError('duration', f'{duration!r} s must be positive and finite')
    axes = [parse_axis(g, base) for g in grid]
    cases = expand(axes)
    names = [a[0] for a in axes]
    if 'speed' not in names:
        if speed is None:
            raise ParameterError('speed', 'not given: give a nut speed [m/s] or a speed axis')
        if not (math.isfinite(speed) and speed != 0.0):
            raise ParameterError('speed', f'{speed!r} m/s must be nonzero and finite')
    rows, complete = run_cases(base, cases, speed, drive, method, duration, workers,
                               scheduler, progress)
    for i, r in enumerate(rows):
        if r is None:
            rows[i] = dict(cases[i], **{c: math.nan for c in COLUMNS})
            rows[i].update(mechanism='', verdict='', error=INTERRUPTED)
    if csv_path:
        write_csv(csv_path, names, rows)
    if plot_path and complete:
        from .plot import plot_map
        plot_map(plot_path, axes, rows, method)
    return dict(names=names, rows=rows, complete=complete,
                boundaries=boundaries(axes, rows), bistable=bistable_ranges(axes, rows),
                worst=_worst(rows))
