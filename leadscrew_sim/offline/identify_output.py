"""
The files of ``identify``: the report, the fitted set as a parameter file, the PNG of the fit.

A file that cannot be written is a one-line :class:`RunError` naming its option.
"""
import numpy as np

from .options import RunError
from ..core import yamlio
from ..core.params import ScrewParams


def write_outputs(args, out, text):
    """
    Write the files the options of ``identify`` ask for, in this order.

    Parameters
    ----------
    args : argparse.Namespace
        The options (``report``, ``output_params``, ``plot``: a path or None).
    out : dict
        What :func:`leadscrew_sim.offline.identify.fit_recording` returned.
    text : str
        The report.

    """
    if args.report:
        write_text(args.report, text + '\n', '--report')
    if args.output_params:
        write_params(args.output_params, out['params'], out['label'], out['res'])
    if args.plot:
        plot(args.plot, out['problem'], out['initial'], out['final'])


def write_text(path, text, option):
    """Write ``text`` to ``path``; a failure is a one-line error naming ``option``."""
    try:
        with open(path, 'w') as fh:
            fh.write(text)
    except OSError as exc:
        raise RunError(f'{option} {path}: {exc.strerror or exc}') from None


def params_document(params, label, res):
    """
    Return the parameter file of a fitted set: ``/**: ros__parameters:``, exact floats.

    Every physics parameter but the injected faults (at their defaults) is
    written, so ``simulate --params`` and the node (whatever its preset)
    rebuild the very same set; PyYAML writes floats by their shortest repr,
    which reads back to the same double.

    Parameters
    ----------
    params : ScrewParams
        The fitted set.
    label : str
        Where the starting values came from.
    res : leadscrew_sim.analysis.identify.fit.FitResult
        The fit (which parameters were identified).

    """
    values = {name: getattr(params, name) for name in ScrewParams.names()
              if not name.startswith('fault_')}
    doc = {'/**': {'ros__parameters': values}}
    ident = [f'{n}={getattr(params, n)!r}' for n, vd in zip(res.names, res.verdicts)
             if vd.identified]
    kept = [n for n, vd in zip(res.names, res.verdicts) if not vd.identified]
    head = (f'# leadscrew_sim identify: starting values from {label}; identified: '
            f'{", ".join(ident) or "none"}')
    if kept:
        head += f'; not identifiable (starting values): {", ".join(kept)}'
    return head + '\n' + yamlio.dump(doc) + '\n'


def write_params(path, params, label, res):
    """Write the parameter file of the fitted set (:func:`params_document`)."""
    write_text(path, params_document(params, label, res), '--output-params')


def plot(path, problem, initial, final):
    """
    Write a PNG of each measured signal: recorded, initial and fitted, with the residuals.

    Parameters
    ----------
    path : str
        The PNG file.
    problem : leadscrew_sim.offline.identify_problem.Problem
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
        raise RunError(f'--plot {path}: {exc.strerror or exc}') from None
    finally:
        plt.close(fig)
