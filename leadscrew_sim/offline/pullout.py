"""
The pull-out torque of a stepper axis against step rate (doc/model.md section 18).

:func:`pullout_curve` measures it on the simulated motor: the axis's motor,
driver and inertias on an ideal load (horizontal, frictionless, backlash-free,
stiff contact), stepped at each rate through the step generator; once it runs
steady, a load torque rises slowly (an axial force on the nut, through the
frictionless thread exactly a torque on the motor) until the rotor slips an
electrical cycle. The load torque at that moment is the pull-out torque (the
viscous torques of the rotor, bearing and guide at that speed come on top).
:func:`write_csv` and :func:`plot_png` write the table and its figure.
"""
import csv
import math

import numpy as np

from ..core.drive_modes import MODE_VELOCITY
from ..core.model import LeadScrewModel
from .options import RunError

#: Step rates [full steps/s] measured by default: 0.1 .. 1 of the axis's max_step_rate.
DEFAULT_SHARES = (0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9, 1.0)

#: CSV columns of the table.
COLUMNS = ('step_rate', 'speed', 'pullout_torque', 'load_angle_reached')


def ideal_load(params):
    """
    Return the axis's motor and driver on the ideal load of :func:`pullout_curve`.

    Parameters
    ----------
    params : ScrewParams
        A stepper axis (``drive_type`` stepper).

    """
    return params.replace(hand='left', inclination=0.0, mu_s=0.0, mu_k=0.0, backlash=0.0,
                          contact_stiffness=max(params.contact_stiffness, 1e9),
                          bearing_coulomb=0.0, guide_coulomb=0.0, collar_mu=0.0,
                          stroke_min=-100.0, stroke_max=100.0, hold_current_delay=3600.0,
                          external_force=0.0, initial_position=0.0)


def pullout_torque(params, rate, ramp=2.0, dt=1e-3):
    """
    Return the pull-out torque [N m] at ``rate`` full steps/s, or 0.0 if it cannot run there.

    Parameters
    ----------
    params : ScrewParams
        The ideal load (:func:`ideal_load`).
    rate : float
        Step rate [full steps/s], at most ``params.max_step_rate``.
    ramp : float
        Time [s] of the load's rise from 0 to 1.2 times the holding torque.
    dt : float
        Step [s].

    """
    m = LeadScrewModel(params, dt=dt)
    w = rate * params.step_angle
    rt = params.lead_ratio
    n0 = int(round((rate / params.step_acceleration + 0.3) / dt))
    n1 = int(round(ramp / dt))
    rows = np.tile([MODE_VELOCITY, math.nan, w, math.nan], (n0 + n1, 1))
    load = np.zeros(n0 + n1)
    load[n0:] = np.linspace(0.0, 1.2 * params.holding_torque, n1)
    r = m.run(None, -load / rt, commands=rows)
    slips = np.flatnonzero(r['lost_full_steps'] != 0)
    if len(slips) == 0:
        return 1.2 * params.holding_torque
    return float(load[slips[0]])


def pullout_curve(params, rates=None, ramp=2.0):
    """
    Return the pull-out table of a stepper axis: one row per step rate.

    Parameters
    ----------
    params : ScrewParams
        A stepper axis; its motor, driver and inertias are measured on the ideal load.
    rates : sequence of float, optional
        Step rates [full steps/s] (default: :data:`DEFAULT_SHARES` of max_step_rate).
    ramp : float
        Time [s] of each load ramp.

    Returns
    -------
    list of dict
        step_rate [full steps/s], speed [rev/s], pullout_torque [N m] (the load
        torque at the first slip; 1.2 holding torque if none) and
        load_angle_reached (False when the rotor slipped before any load: the
        rate cannot be run at all, pullout_torque 0).

    Raises
    ------
    RunError
        If the axis is not a stepper or a rate is outside (0, max_step_rate].

    """
    if params.drive_type != 'stepper':
        raise RunError('pullout needs a stepper axis (drive_type stepper)')
    if rates is None:
        rates = [share * params.max_step_rate for share in DEFAULT_SHARES]
    load = ideal_load(params)
    rows = []
    for rate in rates:
        if not (math.isfinite(rate) and 0.0 < rate <= params.max_step_rate):
            raise RunError(f'step rate {rate!r} full steps/s is outside (0, max_step_rate '
                           f'{params.max_step_rate:g}]')
        torque = pullout_torque(load, rate, ramp)
        rows.append(dict(step_rate=float(rate), speed=rate * params.step_angle / (2 * math.pi),
                         pullout_torque=torque, load_angle_reached=torque > 0.0))
    return rows


def write_csv(rows, path):
    """Write the table ``rows`` (:func:`pullout_curve`) as CSV to ``path``."""
    with open(path, 'w', newline='') as fh:
        w = csv.writer(fh)
        w.writerow(COLUMNS)
        for r in rows:
            w.writerow([repr(r[c]) if isinstance(r[c], float) else r[c] for c in COLUMNS])


def plot_png(rows, params, label, path):
    """
    Write the pull-out curve (torque against step rate, speed on top) as a PNG.

    Parameters
    ----------
    rows : list of dict
        The table of :func:`pullout_curve`.
    params : ScrewParams
        The axis (its holding torque, supply voltage and current).
    label : str
        The axis's name for the title.
    path : str
        The PNG file.

    """
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    rate = [r['step_rate'] for r in rows]
    torque = [r['pullout_torque'] for r in rows]
    fig, ax = plt.subplots(figsize=(7, 4.2))
    ax.plot(rate, torque, 'o-', label='pull-out torque (simulated)')
    ax.axhline(params.holding_torque, color='grey', ls='--', lw=1,
               label=f'holding torque {params.holding_torque:g} N m')
    ax.set_xlabel('step rate [full steps/s]')
    ax.set_ylabel('torque [N m]')
    ax.set_ylim(0.0, 1.1 * params.holding_torque)
    ax.set_title(f'{label}: {params.run_current:g} A, {params.supply_voltage:g} V, '
                 f'{params.microsteps} microsteps')
    top = ax.secondary_xaxis('top', functions=(
        lambda f: f * params.step_angle / (2 * math.pi),
        lambda s: s * 2 * math.pi / params.step_angle))
    top.set_xlabel('speed [rev/s]')
    ax.grid(True, alpha=0.3)
    ax.legend(loc='lower left')
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
