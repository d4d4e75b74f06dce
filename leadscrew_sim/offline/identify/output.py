"""
The files of ``identify``: the report, the fitted set as a parameter file, the PNG of the fit.

A file that cannot be written is a one-line :class:`RunError` naming its option.
"""
import re

import numpy as np

from ..options import option_text, RunError
from ...core import yamlio
from ...core.params import ScrewParams
from ...core.presets import preset_names


def write_outputs(args, out, text, name_of=None):
    """
    Write the files the options of ``identify`` ask for, in this order.

    Parameters
    ----------
    args : argparse.Namespace
        The options (``report``, ``output_params``, ``plot``: a path or None).
    out : dict
        What :func:`leadscrew_sim.offline.identify.run.fit_recording` returned.
    text : str
        The report.
    name_of : callable, optional
        ``name_of(keyword)``: the name of an option the parameter file's
        comments name (default its keyword; :func:`..options.option_text`).

    """
    if args.report:
        write_text(args.report, text + '\n', 'report')
    if args.output_params:
        write_params(args.output_params, out['params'], out['label'], out['res'],
                     getattr(args, 'write_all', False), name_of)
    if args.plot:
        plot(args.plot, out['problem'], out['initial'], out['final'])


def write_text(path, text, option):
    """Write ``text`` to ``path``; a failure is a one-line error naming the option ``option``."""
    try:
        with open(path, 'w') as fh:
            fh.write(text)
    except OSError as exc:
        raise RunError(f'<<{option}>> {path}: {exc.strerror or exc}') from None


def params_document(params, label, res, write_all=False, name_of=None):
    """
    Return the parameter file of a fitted set: ``/**: ros__parameters:``, exact floats.

    By default only the identified values are written, and those exact data
    determine (ideal sensors: no statistical interval; each marked so by a
    comment on its line), after ``preset: <label>``
    when the starting values were a preset (so simulate's ``params`` option and the
    node rebuild the starting set with the identified values in it); each fitted
    parameter left out is named in a comment with why (not identifiable, or the
    fit was rejected). With ``write_all`` every physics parameter but the
    injected faults (at their defaults) is written, the ones not identified
    (their starting values) marked by a comment on their line. PyYAML writes
    floats by their shortest repr, which reads back to the same double.

    Parameters
    ----------
    params : ScrewParams
        The fitted set.
    label : str
        Where the starting values came from (a preset's name, else a file's).
    res : leadscrew_sim.analysis.identify.fit.FitResult
        The fit (which parameters were identified).
    write_all : bool
        Write every value (the ``write_all`` option), not only the identified ones.
    name_of : callable, optional
        ``name_of(keyword)``: the name of an option the comments name (default
        its keyword; :func:`..options.option_text`).

    """
    ident = [n for n, vd in zip(res.names, res.verdicts) if vd.identified]
    exact = [n for n, vd in zip(res.names, res.verdicts) if vd.exact and not vd.identified]
    kept = {n: vd.reason for n, vd in zip(res.names, res.verdicts) if not vd.fitted}
    head = [f'# leadscrew_sim identify: starting values from {label}; identified: '
            f'{", ".join(f"{n}={getattr(params, n)!r}" for n in ident) or "none"}']
    if exact:
        head.append('# determined by exact data (ideal sensors, no statistical interval): '
                    f'{", ".join(f"{n}={getattr(params, n)!r}" for n in exact)}')
    if write_all:
        values = {name: getattr(params, name) for name in ScrewParams.names()
                  if not name.startswith('fault_')}
        if kept:
            head.append('# every value written; those marked "not identified" are the '
                        'starting values')
    else:
        values = {'preset': label} if label in preset_names() else {}
        values.update({n: getattr(params, n) for n in res.names if n in ident or n in exact})
        head.append('# only the identified values (and those exact data determine) are written' + (
            f' (over the preset {label})' if values.get('preset') else
            f' (the other starting values came from {label})'))
        if kept:
            head.append('# left out, not identified (write them with <<write_all>>):')
            head += [f'#   {n}: {" ".join(why.split())}' for n, why in kept.items()]
    body = yamlio.dump({'/**': {'ros__parameters': values}}).split('\n')
    for i, line in enumerate(body):
        m = _KEY.match(line)
        if m and m.group(1) in exact:
            body[i] = f'{line}  # exact data: determined to the fit\'s resolution, no interval'
        elif m and write_all and m.group(1) in kept:
            body[i] = f'{line}  # not identified: {_short(kept[m.group(1)])}'
    return option_text('\n'.join(head + body) + '\n', name_of)


#: A parameter's line in the dumped file: its name.
_KEY = re.compile(r'^    ([A-Za-z_][A-Za-z0-9_]*):')


def _short(reason):
    """Return the kind of a verdict's reason: its text up to the first colon."""
    return ' '.join(reason.split(':', 1)[0].split())


def write_params(path, params, label, res, write_all=False, name_of=None):
    """Write the parameter file of the fitted set (:func:`params_document`)."""
    write_text(path, params_document(params, label, res, write_all, name_of), 'output_params')


def plot(path, problem, initial, final):
    """
    Write a PNG of each measured signal: recorded, initial and fitted, with the residuals.

    Parameters
    ----------
    path : str
        The PNG file.
    problem : leadscrew_sim.offline.identify.problem.Problem
        The recording set up for the fit.
    initial, final : dict
        The re-simulated columns with the starting and the fitted values.

    """
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    meas = problem.measurements
    n = meas.n
    t = (np.arange(n) + 1) * problem.dt
    fig, axes = plt.subplots(len(meas.names), 2, figsize=(12, 3.2 * len(meas.names)),
                             squeeze=False, sharex=True)
    d0, d1 = meas.differences(initial), meas.differences(final)
    for i, name in enumerate(meas.names):
        m = meas.mask[i]
        unit = meas.units[name]
        ax, axr = axes[i]

        def compared(y, m=m):
            """Return ``y`` with gaps (NaN) where the signal is not compared."""
            return np.where(m, y, np.nan)

        ax.plot(t, compared(meas.data[i]), '.', ms=1.5, color='0.4', label='recorded')
        # the simulated signals with the offset the fit removed, on the recorded one's level
        ax.plot(t, compared(meas.data[i] + d0[i]), lw=1.0, label='initial')
        ax.plot(t, compared(meas.data[i] + d1[i]), lw=1.0, label='fitted')
        ax.set_ylabel(f'{name} [{unit}]')
        ax.legend(loc='best', fontsize=8)
        axr.plot(t, compared(d0[i]), lw=0.6, alpha=0.6, label='initial')
        axr.plot(t, compared(d1[i]), lw=0.6, label='fitted')
        sigma = problem.noise[name][0]
        axr.axhline(sigma, color='k', lw=0.5, ls='--')
        axr.axhline(-sigma, color='k', lw=0.5, ls='--', label='+-noise sigma')
        axr.set_ylabel(f'residual [{unit}]')
        axr.legend(loc='best', fontsize=8)
    for ax in axes[-1]:
        ax.set_xlabel('time [s]')
    fig.tight_layout()
    try:
        fig.savefig(path, dpi=90)
    except OSError as exc:
        raise RunError(f'<<plot>> {path}: {exc.strerror or exc}') from None
    finally:
        plt.close(fig)
