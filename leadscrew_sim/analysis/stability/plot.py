"""
The PNG map of a stability table (matplotlib, imported lazily, Agg backend).

One axis: growth rate (linear) and the large start's amplitude (nonlinear)
against it. Two or three axes: a map over the first two, coloured by the
growth rate (linear; a diverging scale about 0) or else by the large start's
amplitude, with the linear boundary (growth_rate = 0) drawn as a contour and
bistable cases marked; a third axis gives one panel per value. Units follow
the parameters' descriptors.
"""
import dataclasses
import math

import numpy as np

from ...core.params import ScrewParams

__all__ = ['plot_map']

_UNITS = {f.name: f.metadata.get('unit', '-') for f in dataclasses.fields(ScrewParams)}
_UNITS['speed'] = 'm/s'


def _label(name):
    unit = _UNITS.get(name, '-')
    return name if unit in ('-', '') else f'{name} [{unit}]'


def _grid_values(rows, key, shape):
    return np.array([r[key] for r in rows], dtype=float).reshape(shape)


def _panel(ax, fig, axes, rows, method):
    (nx, xs), (ny, ys) = axes[0], axes[1]
    shape = (len(xs), len(ys))
    x, y = np.meshgrid(np.asarray(xs, float), np.asarray(ys, float), indexing='ij')
    g = _grid_values(rows, 'growth_rate', shape)
    if method != 'nonlinear' and np.isfinite(g).any():
        lim = np.nanmax(np.abs(g)) or 1.0
        mesh = ax.pcolormesh(x, y, g, cmap='coolwarm', shading='nearest',
                             norm=_sym_norm(lim))
        fig.colorbar(mesh, ax=ax, label='growth rate [1/s]')
        if np.nanmin(g) < 0.0 < np.nanmax(g):
            ax.contour(x, y, g, levels=[0.0], colors='k', linewidths=1.5)
    else:
        amp = _grid_values(rows, 'amplitude_large', shape)
        mesh = ax.pcolormesh(x, y, amp, cmap='viridis', shading='nearest')
        fig.colorbar(mesh, ax=ax, label='amplitude, large start [m/s]')
    bi = np.array([r['verdict'] == 'bistable' for r in rows]).reshape(shape)
    if bi.any():
        ax.plot(x[bi], y[bi], 'k^', ms=6, mfc='none', label='bistable')
        ax.legend(loc='best', fontsize=8)
    from matplotlib.ticker import NullFormatter
    for setter, axis, vals in ((ax.set_xscale, ax.xaxis, xs), (ax.set_yscale, ax.yaxis, ys)):
        if len(vals) > 2 and all(v > 0 for v in vals) and _is_log(vals):
            setter('log')
            axis.set_minor_formatter(NullFormatter())
    ax.set_xlabel(_label(nx))
    ax.set_ylabel(_label(ny))


def _sym_norm(lim):
    from matplotlib.colors import SymLogNorm
    return SymLogNorm(linthresh=max(lim * 1e-4, 1e-9), vmin=-lim, vmax=lim)


def _is_log(vals):
    r = np.asarray(vals, float)
    return np.allclose(r[1:] / r[:-1], r[1] / r[0], rtol=1e-6) and r[1] / r[0] != 1.0


def _line(ax, axes, rows, method):
    name, xs = axes[0]
    xs = np.asarray(xs, float)
    if method != 'nonlinear':
        g = np.array([r['growth_rate'] for r in rows], float)
        ax.plot(xs, g, 'o-', color='C0')
        ax.axhline(0.0, color='k', lw=0.8)
        ax.set_ylabel('growth rate [1/s]', color='C0')
        ax.set_yscale('symlog', linthresh=max(1e-3, np.nanmax(np.abs(g)) * 1e-4)
                      if np.isfinite(g).any() else 1.0)
    if method != 'linear':
        ax2 = ax.twinx() if method == 'both' else ax
        amp = np.array([r['amplitude_large'] for r in rows], float)
        ax2.plot(xs, amp, 's--', color='C1', label='large start')
        ax2.plot(xs, [r['amplitude_small'] for r in rows], 'x:', color='C2',
                 label='small start')
        bi = [r['verdict'] == 'bistable' for r in rows]
        if any(bi):
            ax2.plot(xs[bi], amp[bi], 'k^', ms=8, mfc='none', label='bistable')
        ax2.set_ylabel('amplitude [m/s]', color='C1')
        ax2.legend(loc='best', fontsize=8)
    if all(v > 0 for v in xs) and len(xs) > 2 and _is_log(xs):
        ax.set_xscale('log')
    ax.set_xlabel(_label(name))


def plot_map(path, axes, rows, method='both'):
    """
    Write the PNG map of a stability table.

    Parameters
    ----------
    path : str or pathlib.Path
        The PNG file.
    axes : list of (str, list)
        The parsed axes (0 to 3).
    rows : list of dict
        The rows in case order.
    method : str
        'linear', 'nonlinear' or 'both' (what the rows hold).

    """
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    panels = len(axes[2][1]) if len(axes) == 3 else 1
    fig, axs = plt.subplots(1, panels, figsize=(6.4 * panels, 4.8), squeeze=False)
    if len(axes) <= 1:
        if axes:
            _line(axs[0][0], axes, rows, method)
        else:
            axs[0][0].text(0.5, 0.5, 'one case: see the printed summary', ha='center')
    else:
        per = math.prod(len(a[1]) for a in axes[:2])
        for k in range(panels):
            sub = rows[k::panels] if len(axes) == 3 else rows
            _panel(axs[0][k], fig, axes[:2], sub[:per], method)
            if len(axes) == 3:
                axs[0][k].set_title(f'{_label(axes[2][0])} = {axes[2][1][k]:.4g}')
    fig.suptitle('stability of steady sliding (black line: linear boundary)')
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
