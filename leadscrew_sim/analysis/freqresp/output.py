"""
The CSV and the Bode PNG of frequency responses (matplotlib imported lazily, Agg backend).

CSV: one row per frequency and amplitude, columns :data:`COLUMNS`:
``frequency`` [Hz], ``magnitude_db`` [dB of the output unit over the input
unit, SI], ``phase_deg`` [deg, unwrapped along frequency], ``coherence`` [-]
(empty for the linear model), ``amplitude`` [the input's SI unit] (empty for
the linear model). An unknown value is an empty cell, never 'nan' or 'inf':
the linear model's coherence and amplitude, a point without a result (a
latched drive fault), the dB of a zero gain. PNG: magnitude and phase against frequency (log), one
curve per amplitude, the linear model dashed, the coherence below.
"""
import csv
import math

import numpy as np

__all__ = ['COLUMNS', 'plot_bode', 'UNITS', 'write_csv']

COLUMNS = ('frequency', 'magnitude_db', 'phase_deg', 'coherence', 'amplitude')

#: The SI unit of every input and output name (loop quantities are dimensionless).
UNITS = dict(torque='N m', velocity_command='m/s', position_command='m', external_force='N',
             motor_angle='rad', motor_velocity='rad/s', nut_position='m', nut_velocity='m/s',
             thread_force='N', following_error='rad', motor_torque='N m',
             velocity_loop='N m', position_loop='rad/s', L='-', S='-', T='-')


def _num(x):
    """Return a cell: repr of a finite number, '' for an unknown (NaN) or non-finite one."""
    x = float(x)
    return repr(x) if math.isfinite(x) else ''


def write_csv(path, responses):
    """
    Write the responses to a CSV file (:data:`COLUMNS`), one block per response.

    Parameters
    ----------
    path : str or pathlib.Path
        The file.
    responses : list of FrequencyResponse
        Written in order.

    """
    with open(path, 'w', newline='') as f:
        w = csv.writer(f)
        w.writerow(COLUMNS)
        for r in responses:
            for fi, m, ph, c in zip(r.frequency, r.magnitude_db, r.phase_deg, r.coherence):
                w.writerow([_num(fi), _num(m), _num(ph), _num(c), _num(r.amplitude)])


def _title(r):
    if r.output in ('L', 'S', 'T'):
        return f'{r.input.replace("_", " ")}: {r.output}'
    return (f'{r.input} [{UNITS.get(r.input, "-")}] -> '
            f'{r.output} [{UNITS.get(r.output, "-")}]')


def plot_bode(path, responses, linear=None, title=None):
    """
    Write a Bode PNG: magnitude, phase and coherence against frequency.

    Parameters
    ----------
    path : str or pathlib.Path
        The PNG.
    responses : list of FrequencyResponse
        Measured (or linear) responses, one curve each.
    linear : FrequencyResponse, optional
        The linear model, drawn dashed over them.
    title : str, optional
        The figure's title (default: input -> output).

    """
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    fig, (am, ap, ac) = plt.subplots(3, 1, figsize=(7.5, 8.0), sharex=True,
                                     gridspec_kw=dict(height_ratios=[3, 2, 1.2]))
    unit = UNITS.get(responses[0].input if responses else linear.input, '-')
    ref = None
    for i, r in enumerate(responses):
        label = (r.source if math.isnan(r.amplitude)
                 else f'{r.source}, amplitude {r.amplitude:.3g} {unit}')
        am.semilogx(r.frequency, r.magnitude_db, 'o-', ms=3, color=f'C{i}', label=label)
        ph = r.phase_deg
        if ref is None and np.isfinite(ph).any():
            ref = ph[np.isfinite(ph)][0]
        elif ref is not None and np.isfinite(ph).any():   # every curve on the first's branch
            ph = ph - 360.0 * np.round((ph[np.isfinite(ph)][0] - ref) / 360.0)
        ap.semilogx(r.frequency, ph, 'o-', ms=3, color=f'C{i}')
        if np.isfinite(r.coherence).any():
            ac.semilogx(r.frequency, r.coherence, 'o-', ms=3, color=f'C{i}')
    if linear is not None:
        ph = linear.phase_deg
        if ref is not None and np.isfinite(ref):   # the same branch of the phase
            ph = ph - 360.0 * np.round((ph[0] - ref) / 360.0)
        am.semilogx(linear.frequency, linear.magnitude_db, 'k--', lw=1.2, label='linear model')
        ap.semilogx(linear.frequency, ph, 'k--', lw=1.2)
    am.set_ylabel('magnitude [dB]')
    ap.set_ylabel('phase [deg]')
    ac.set_ylabel('coherence [-]')
    ac.set_ylim(0.0, 1.05)
    ac.set_xlabel('frequency [Hz]')
    for ax in (am, ap, ac):
        ax.grid(True, which='both', alpha=0.3)
    am.legend(loc='best', fontsize=8)
    first = responses[0] if responses else linear
    am.set_title(title or _title(first))
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
