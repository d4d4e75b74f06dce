"""
The classic derived figures of an identification run, from its arrays (no ROS, no files).

Inputs are per-sample arrays of one run: time [s], the command in force at
each sample (:func:`hold_series` resamples recorded command messages), and
the measured states (motor torque [N m] and velocity [rad/s] of the screw
joint, nut position [m] and velocity [m/s]). The segments are found from
the command itself (a ramp away from the centre, a run of one constant
speed, a run of one constant position target), so the figures need no
profile timing and work on any recording of the profiles of
:mod:`.excitation`.

- :func:`breakaway_torques`: the motor torque at which the nut starts to
  move in each torque direction. Motion starts at the first sample where the
  nut is more than ``threshold`` (default 1 um) from where it was when the
  torque left the centre: above the flank deflection a changing torque
  causes on a stuck thread and, by default, above the sensor noise.
- :func:`stribeck_points`: mean steady torque against mean nut speed on every
  constant-speed level, after ``settle`` s.
- :func:`efficiencies`: forward efficiency (load power / motor power while
  the motor drives the load) and back-driving efficiency (motor power
  returned / load power while the load drives) on every level. When the axis
  self-locks in motion the motor still delivers power while the load
  descends, so the back-driving efficiency, the power the motor receives
  over the power the load gives, is <= 0 (the closed form
  (tan(lambda) - mu') / (tan(lambda) (1 + mu' tan(lambda))) is negative
  then, too).
- :func:`thermal_drift`: ISO 230-3 warm-up drift: where the nut stands at
  each measurement stop against its target, over time.
- :func:`reversal_error`: ISO 230-2 bidirectional figures: at each target
  the mean positioning deviation approaching from below and from above, the
  reversal B_i = mean up - mean down, its mean and its largest magnitude.
"""
import dataclasses
import math

import numpy as np

__all__ = ['Breakaway', 'StribeckPoint', 'ReversalFigures', 'axial_load', 'breakaway_torques',
           'derived_figures', 'efficiencies', 'hold_series',
           'reversal_error', 'stribeck_points']


@dataclasses.dataclass(frozen=True)
class Breakaway:
    """Motion onset in one torque direction: +1 toward +theta, -1 toward -theta."""

    direction: int
    torque: float           # motor torque at the onset [N m]
    time: float             # time of the onset [s]
    center: float           # torque the ramp started from [N m]


@dataclasses.dataclass(frozen=True)
class StribeckPoint:
    """The steady part of one constant-speed level."""

    command: float          # commanded nut velocity [m/s]
    speed: float            # mean nut velocity [m/s]
    torque: float           # mean motor torque [N m]
    torque_std: float       # its standard deviation [N m]
    motor_power: float      # mean of torque x motor velocity [W]
    t0: float               # measurement window [s]
    t1: float
    samples: int


@dataclasses.dataclass(frozen=True)
class ReversalFigures:
    """ISO 230-2 bidirectional figures of a positioning run [m]."""

    targets: tuple          # target positions
    mean_up: tuple          # mean deviation approaching from below, per target
    mean_down: tuple        # from above
    reversal: tuple         # B_i = mean_up - mean_down
    mean_reversal: float    # mean of B_i
    max_reversal: float     # largest |B_i|
    approaches: tuple       # (n up, n down) per target


def hold_series(times, values, t, before=math.nan):
    """
    Return the zero-order hold of a series at the times ``t``: the last value at or before.

    Parameters
    ----------
    times : array_like of float
        Sorted times of the values [s] (e.g. the log times of the command messages).
    values : array_like of float
        The values at those times.
    t : array_like of float
        Times to sample at [s].
    before : float
        Value before the first time.

    """
    times, values = np.asarray(times, dtype=float), np.asarray(values, dtype=float)
    i = np.searchsorted(times, np.asarray(t, dtype=float), side='right') - 1
    out = values[np.clip(i, 0, max(len(values) - 1, 0))] if len(values) else \
        np.full(np.shape(t), before)
    return np.where(i >= 0, out, before)


def _runs(command):
    """Return [(start, stop)] index ranges of equal consecutive values of ``command``."""
    c = np.asarray(command, dtype=float)
    if not len(c):
        return []
    change = np.flatnonzero(c[1:] != c[:-1]) + 1
    edges = np.concatenate(([0], change, [len(c)]))
    return list(zip(edges[:-1].tolist(), edges[1:].tolist()))


def breakaway_torques(t, command, motor_torque, nut_position, threshold=1e-6):
    """
    Return {+1: Breakaway or None, -1: ...}: where the nut starts to move on each torque ramp.

    The centre is the command at the first sample; a ramp in direction s is
    the first stretch of samples where s (command - centre) > 0. Its onset is
    the first sample of the stretch where the nut is farther than
    ``threshold`` from its position at the sample before the stretch; the
    figure is the measured motor torque there. None: no motion on that ramp.

    Parameters
    ----------
    t : array_like of float
        Sample times [s].
    command : array_like of float
        Torque command in force at each sample [N m].
    motor_torque : array_like of float
        Measured (applied) motor torque [N m].
    nut_position : array_like of float
        Measured nut position [m].
    threshold : float
        Nut travel that counts as motion [m].

    """
    t, c = np.asarray(t, dtype=float), np.asarray(command, dtype=float)
    tq, x = np.asarray(motor_torque, dtype=float), np.asarray(nut_position, dtype=float)
    center = float(c[0])
    out = {}
    for s in (1, -1):
        out[s] = None
        inside = np.flatnonzero(s * (c - center) > 0.0)
        if not len(inside):
            continue
        a = int(inside[0])
        gaps = np.flatnonzero(np.diff(inside) > 1)
        b = int(inside[gaps[0]]) + 1 if len(gaps) else int(inside[-1]) + 1
        ref = x[max(a - 1, 0)]
        moved = np.flatnonzero(np.abs(x[a:b] - ref) > threshold)
        if len(moved):
            i = a + int(moved[0])
            out[s] = Breakaway(s, float(tq[i]), float(t[i]), center)
    return out


def stribeck_points(t, command, motor_torque, motor_velocity, nut_velocity, settle=0.3,
                    min_window=0.05):
    """
    Return a StribeckPoint per level of constant non-zero speed command, in time order.

    Parameters
    ----------
    t : array_like of float
        Sample times [s].
    command : array_like of float
        Nut velocity command in force at each sample [m/s].
    motor_torque : array_like of float
        Measured motor torque [N m].
    motor_velocity : array_like of float
        Measured motor (screw joint) velocity [rad/s].
    nut_velocity : array_like of float
        Measured nut velocity [m/s].
    settle : float
        Start of each level left out [s].
    min_window : float
        Shortest measurement window that makes a point [s].

    """
    t, c = np.asarray(t, dtype=float), np.asarray(command, dtype=float)
    tq, w = np.asarray(motor_torque, dtype=float), np.asarray(motor_velocity, dtype=float)
    v = np.asarray(nut_velocity, dtype=float)
    points = []
    for a, b in _runs(c):
        if c[a] == 0.0 or not math.isfinite(c[a]):
            continue
        sel = np.arange(a, b)[t[a:b] >= t[a] + settle]
        if len(sel) < 2 or t[sel[-1]] - t[sel[0]] < min_window:
            continue
        power = tq[sel] * w[sel]
        points.append(StribeckPoint(float(c[a]), float(np.mean(v[sel])),
                                    float(np.mean(tq[sel])), float(np.std(tq[sel])),
                                    float(np.mean(power)), float(t[sel[0]]),
                                    float(t[sel[-1]]), len(sel)))
    return points


def axial_load(params, external_force=None):
    """
    Return the axial load W [N] that opposes motion toward +x: m g sin(beta) - F_ext.

    Parameters
    ----------
    params : ScrewParams
        The axis (moving mass, gravity, inclination, external_force).
    external_force : float, optional
        External force on the nut along +x [N] (default the parameter's).

    """
    f = params.external_force if external_force is None else external_force
    return params.moving_mass * params.gravity * math.sin(params.inclination) - f


def efficiencies(points, load):
    """
    Return [(point, kind, eta)] per level and {kind: eta at the fastest level of that kind}.

    kind is ``'forward'`` where the motor raises the load (load power W v > 0):
    eta = W v / P_motor; ``'backdrive'`` where the load descends (W v < 0):
    eta = P_motor / (W v), the power the motor receives over the power the
    load gives, <= 0 when the axis self-locks in motion. Levels whose mean
    speed is below half the commanded one (stuck, or stick-slip) are left
    out. With no load (W = 0) the efficiency is undefined: an empty result.

    Parameters
    ----------
    points : list of StribeckPoint
        The levels (:func:`stribeck_points`).
    load : float
        Axial load opposing +x [N] (:func:`axial_load`).

    """
    rows, best = [], {}
    if load == 0.0:
        return rows, best
    fastest = {}
    for p in points:
        p_load = load * p.speed
        if p_load == 0.0 or p.motor_power == 0.0 or not p.speed / p.command >= 0.5:
            continue                # no steady motion at about the commanded speed
        kind = 'forward' if p_load > 0.0 else 'backdrive'
        eta = p_load / p.motor_power if kind == 'forward' else p.motor_power / p_load
        rows.append((p, kind, eta))
        if kind not in fastest or abs(p.speed) > fastest[kind]:
            fastest[kind] = abs(p.speed)
            best[kind] = eta
    return rows, best


def reversal_error(t, command, nut_position, window=0.2, min_dwell=0.1):
    """
    Return the ISO 230-2 ReversalFigures of a bidirectional positioning run (None: no pairs).

    A dwell is a run of one position command lasting at least ``min_dwell``;
    its approach direction is the sign of its target minus the command just
    before it; its reading the mean nut position over its last ``window`` s
    (at most half the dwell). Targets equal to 1 nm are one target. Only
    targets approached from both sides count.

    Parameters
    ----------
    t : array_like of float
        Sample times [s].
    command : array_like of float
        Nut position command in force at each sample [m].
    nut_position : array_like of float
        Measured nut position [m].
    window : float
        Reading window at the end of each dwell [s].
    min_dwell : float
        Shortest run of one command that counts as a dwell [s].

    """
    t, c = np.asarray(t, dtype=float), np.asarray(command, dtype=float)
    x = np.asarray(nut_position, dtype=float)
    found = {}
    for a, b in _runs(c):
        if a == 0 or not math.isfinite(c[a]) or t[b - 1] - t[a] < min_dwell:
            continue
        side = 1 if c[a] > c[a - 1] else -1
        w = min(window, 0.5 * (t[b - 1] - t[a]))
        sel = t[a:b] >= t[b - 1] - w
        deviation = float(np.mean(x[a:b][sel])) - float(c[a])
        key = round(float(c[a]) * 1e9)
        found.setdefault(key, (float(c[a]), {1: [], -1: []}))[1][side].append(deviation)
    rows = [found[k] for k in sorted(found) if all(found[k][1].values())]
    if not rows:
        return None
    targets = tuple(r[0] for r in rows)
    up = tuple(float(np.mean(r[1][1])) for r in rows)
    down = tuple(float(np.mean(r[1][-1])) for r in rows)
    b = tuple(u - d for u, d in zip(up, down))
    return ReversalFigures(targets, up, down, b, float(np.mean(b)), float(np.max(np.abs(b))),
                           tuple((len(r[1][1]), len(r[1][-1])) for r in rows))


def thermal_drift(t, command, position, window=0.2, min_dwell=0.1):
    """
    Return the drift at the measurement stops of a warm-up run (ISO 230-3): a list of rows.

    A stop is a run of one position command lasting at least ``min_dwell``
    [s]; its reading is the mean of ``position`` (where the nut stands, e.g.
    the true position in the frame, the nut position plus the screw's
    thermal growth) over its last ``window`` s (at most half the stop). Each
    row is (end time [s], target [m], drift [m]: the reading less the
    target, ``index`` of the stop's last sample).

    Parameters
    ----------
    t : array_like of float
        Sample times [s].
    command : array_like of float
        Nut position command in force at each sample [m].
    position : array_like of float
        Where the nut stands at each sample [m].
    window : float
        Reading window at the end of each stop [s].
    min_dwell : float
        Shortest run of one command that counts as a stop [s].

    """
    t, c = np.asarray(t, dtype=float), np.asarray(command, dtype=float)
    x = np.asarray(position, dtype=float)
    rows = []
    for a, b in _runs(c):
        if not math.isfinite(c[a]) or t[b - 1] - t[a] < min_dwell:
            continue
        w = min(window, 0.5 * (t[b - 1] - t[a]))
        sel = t[a:b] >= t[b - 1] - w
        rows.append((float(t[b - 1]), float(c[a]), float(np.mean(x[a:b][sel])) - float(c[a]),
                     b - 1))
    return rows


def derived_figures(kind, run, load=None, threshold=1e-6, settle=0.3):
    """
    Return the figures of one profile kind from the arrays of a run (a dict).

    Parameters
    ----------
    kind : str
        The profile name: ``breakaway``, ``sweep``, ``reversals`` or ``iso230``.
    run : dict of numpy.ndarray
        ``time`` [s], ``command`` (in force per sample), ``motor_torque`` [N m],
        ``motor_velocity`` [rad/s], ``nut_position`` [m], ``nut_velocity`` [m/s].
    load : float, optional
        Axial load opposing +x [N] for the efficiencies (sweep).
    threshold : float
        Motion threshold of the breakaway [m].
    settle : float
        Settling time of each speed level [s].

    """
    t, c = run['time'], run['command']
    if kind == 'breakaway':
        return {'breakaway': breakaway_torques(t, c, run['motor_torque'], run['nut_position'],
                                               threshold)}
    if kind == 'sweep':
        pts = stribeck_points(t, c, run['motor_torque'], run['motor_velocity'],
                              run['nut_velocity'], settle)
        out = {'stribeck': pts}
        if load is not None:
            out['efficiency'] = efficiencies(pts, load)
        return out
    if kind in ('reversals', 'iso230'):
        return {'reversal': reversal_error(t, c, run['nut_position'])}
    raise ValueError(f'no derived figures for {kind!r}')
