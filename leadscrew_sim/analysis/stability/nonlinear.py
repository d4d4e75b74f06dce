"""
Nonlinear check of steady sliding: the full model run from two starts.

:func:`nonlinear_stability` puts the model onto the steady sliding state of
:func:`.operating_point.operating_point` and runs it twice for ``duration``:
the small start perturbs the nut velocity by SMALL_PERTURBATION of the speed;
the large start has the thread stuck (screw and nut at rest) while the drive
keeps turning, so the coupling (or the drive) winds up as in stick-slip. Over
the last MEASURED share of each run it measures the nut velocity's half
peak-to-peak amplitude [m/s]; over the large start's window also the stick
fraction (share of steps with the thread stuck, over the whole periods
between the first and the last upward crossing when there are two) and the
period (mean spacing of the upward crossings of the window's mean velocity,
linearly interpolated).

Drives: 'velocity' is the model's own servo drive in velocity mode (sampled
at its drive rate, as simulated). 'ideal' prescribes the motor angle: the
motor inertia is raised to IDEAL_MOTOR_INERTIA, its torque each step is the
coupling torque of the step's start (no net acceleration), and after each
step the motor's angle and rate are put back on q_m0 + Omega t (with a rigid
coupling the screw's, which is then the prescribed body).

Verdict: a run oscillates when its amplitude, or the departure of its mean
nut velocity from the speed (a nut still stuck, or stuck for longer than the
window), reaches OSCILLATING of the speed; the small start oscillating:
limit_cycle; only the large one: bistable; neither: stable. A stick-slip
period longer than the measured window therefore shows as an oscillation
without a period: give a longer ``duration`` at low speeds.
"""
import dataclasses
import math

import numpy as np

from ...core.drive_modes import MODE_VELOCITY
from ...core.model import LeadScrewModel
from ...core.params import ParameterError
from ...core.steady import place_sliding, run_prescribed_motor
from .operating_point import operating_point

__all__ = ['measure', 'nonlinear_stability', 'OSCILLATING', 'VERDICTS']

SMALL_PERTURBATION = 0.02       #: nut velocity perturbation of the small start [share of v]
MEASURED = 0.5                  #: share of each run measured (the end of it)
OSCILLATING = 0.05              #: amplitude that counts as an oscillation [share of |v|]
IDEAL_MOTOR_INERTIA = 10.0      #: motor inertia of the prescribed motor [kg m^2] (the bound)
MODELS_KEPT = 256               #: models a ``models`` dict keeps for reuse (the newest)
#: The verdicts of the CSV column ``verdict``.
VERDICTS = ('stable', 'limit_cycle', 'bistable')


def _run_velocity(model, op, n):
    """Run n steps under the held velocity command; return (nut velocity, stuck)."""
    hs = model.params.hand_sign
    rows = np.tile([[MODE_VELOCITY, math.nan, hs * op['w_ref'], 0.0]], (n, 1))
    res = model.run(None, commands=rows, values=('nut_velocity', 'stuck'))
    return res['nut_velocity'], res['stuck'].astype(float)


def _run_ideal(model, op, n):
    """Run n steps with the motor (or rigid screw) angle prescribed; see the module doc."""
    return run_prescribed_motor(model, n, op['omega'])


def measure(velocity, stuck, dt):
    """
    Return (amplitude [m/s], stick fraction [-], period [s]) of a measured window.

    Parameters
    ----------
    velocity : numpy.ndarray
        Nut velocity of each step [m/s].
    stuck : numpy.ndarray
        1.0 where the thread is stuck, else 0.0.
    dt : float
        Step [s].

    """
    amp = 0.5 * float(velocity.max() - velocity.min())
    d = velocity - velocity.mean()
    up = np.nonzero((d[:-1] < 0.0) & (d[1:] >= 0.0))[0]
    if len(up) >= 2:
        frac = -d[up] / (d[up + 1] - d[up])
        times = (up + frac) * dt
        period = float((times[-1] - times[0]) / (len(times) - 1))
        share = float(stuck[up[0] + 1:up[-1] + 1].mean())   # over whole periods
    else:
        period, share = math.nan, float(stuck.mean())
    return amp, share, period


def _one_run(model, op, duration, dt, stuck):
    """Run one start from a model at rest; return (amplitude, stick share, period, |mean - v|)."""
    place_sliding(model, op, stuck, 1.0 if stuck else 1.0 + SMALL_PERTURBATION)
    n = max(4, int(round(duration / dt)))
    run = _run_ideal if op['drive'] == 'ideal' else _run_velocity
    vel, stk = run(model, op, n)
    if not np.isfinite(vel).all():
        raise ValueError(f'speed: the run at {op["speed"]!r} m/s went non-finite')
    k = int(n * (1.0 - MEASURED))
    amp, share, period = measure(vel[k:], stk[k:], dt)
    return amp, share, period, abs(float(vel[k:].mean()) - op['speed'])


def nonlinear_stability(params, speed, drive='velocity', duration=2.0, dt=1e-3, models=None):
    """
    Run the full model from steady sliding, a small and a large start, and judge it.

    Parameters
    ----------
    params : ScrewParams
        The axis (single nut).
    speed : float
        Nut speed [m/s], nonzero; sign = direction along +x.
    drive : str
        'velocity' or 'ideal' (see the module doc).
    duration : float
        Length of each run [s].
    dt : float
        Step of the runs (the recorded samples) [s].
    models : dict, optional
        Models built by earlier calls, by (params, drive, dt): a call with the
        same ones resets and reuses its model instead of building one (a reset
        model is a new one, so the result is the same bit for bit); it keeps
        the newest MODELS_KEPT.

    Returns
    -------
    dict
        verdict (one of VERDICTS), amplitude_small, amplitude_large [m/s],
        stick_fraction [-] and period [s] (large start; NaN without two crossings
        or with an amplitude below OSCILLATING of the speed).

    Raises
    ------
    ParameterError
        If the steady state does not exist, the duration is not positive, or
        the nut would reach an end stop within the run.

    """
    if not (duration > 0.0 and math.isfinite(duration)):
        raise ParameterError('duration', f'{duration!r} s must be positive and finite')
    op = operating_point(params, speed, drive)
    room = (params.stroke_max if speed > 0 else params.stroke_min) - params.initial_position
    if abs(speed) * duration >= 0.9 * abs(room):
        raise ParameterError('duration', f'{duration!r} s at {speed!r} m/s travels beyond '
                             f'90 % of the {abs(room):.4g} m to the end stop')
    key = (params, drive, dt)
    model = models.get(key) if models is not None else None
    if model is None:
        run_params = (dataclasses.replace(params, motor_inertia=IDEAL_MOTOR_INERTIA)
                      if drive == 'ideal' else params)
        model = LeadScrewModel(run_params, dt=dt)
        if models is not None:
            if len(models) >= MODELS_KEPT:
                models.pop(next(iter(models)))    # the oldest
            models[key] = model
    else:
        model.reset()
    a_small, _, _, off_small = _one_run(model, op, duration, dt, stuck=False)
    model.reset()
    a_large, frac, period, off_large = _one_run(model, op, duration, dt, stuck=True)
    tol = OSCILLATING * abs(speed)
    if max(a_small, off_small) >= tol:
        verdict = 'limit_cycle'
    elif max(a_large, off_large) >= tol:
        verdict = 'bistable'
    else:
        verdict = 'stable'
    if a_large < tol:
        period = math.nan
    return dict(verdict=verdict, amplitude_small=a_small, amplitude_large=a_large,
                stick_fraction=frac, period=period)
