"""
What a motion cannot show: the parameters a re-simulated run leaves undetermined, and why.

Some parameters act only through an event or a range of the motion: the
backlash only when the thread contact changes flank (a reversal of the
load), the static friction only when the thread breaks away from
standstill or slides slowly in contact (:func:`static_episodes`), the
kinetic friction only while it slides, the screw's bearing only while the
screw turns and the nut's guide only while the nut moves (by more than the
settling of a still axis), and the shape of
the friction curve (Stribeck velocity and exponent, viscous slope) only
when it slides at more than one speed (at a single speed they, the kinetic
friction and the Coulomb terms add up to one constant torque). A run
without that event or range cannot determine the parameter, however
small its Jacobian's interval looks on exact data, where a few steps of
speed change give it a nonzero but meaningless sensitivity.
:func:`motion_degeneracies` reads them from the re-simulated columns of the
steps a fit compares (``model.run``'s ``contact``, ``stick_a`` and
``sliding_velocity``); a parameter named there is judged "not identifiable"
with the reason, whatever its Jacobian (:func:`.data.judge`).
"""
import numpy as np

#: Band about the median sliding speed [fraction of it] and the share of the sliding steps
#: within it that make a run's sliding "a single speed".
ONE_SPEED_BAND, ONE_SPEED_SHARE = 0.1, 0.95

#: Sliding speed [m/s] below which the thread counts as not sliding (the solver's round-off).
SLIDING = 1e-12

#: The parameters of the friction curve's shape, which one sliding speed cannot separate.
SHAPE = ('stribeck_velocity', 'stribeck_exponent', 'mu_viscous')

#: Travel below which a body counts as never having moved: the settling of a still axis
#: within its contact compliance (nanometres) moves the nut and the screw, yet shows no
#: friction law. Nut [m]: a micron, below a lead screw axis's positioning resolution;
#: screw [rad]: 1e-3 rad, below a count of a 4096-count encoder.
MOVED_NUT, MOVED_SCREW = 1e-6, 1e-3

#: The parameters of the screw's bearing and the nut's guide, and the column whose travel
#: shows each: they act only while that body moves.
BODIES = (('screw_velocity', MOVED_SCREW, 'rad', 'the screw never turned',
           ('bearing_coulomb', 'bearing_viscous')),
          ('nut_velocity', MOVED_NUT, 'm', 'the nut never moved',
           ('guide_coulomb', 'guide_viscous')))


def motion_degeneracies(cols, curve=None):
    """
    Return name -> why the motion of re-simulated columns ``cols`` cannot determine it.

    Parameters
    ----------
    cols : dict
        ``model.run`` columns of the steps compared: ``contact`` (the thread
        flank, 0 when none), ``stick_a`` (1 while stuck), ``sliding_velocity``
        [m/s].
    curve : tuple, optional
        (Stribeck velocity [m/s], Stribeck exponent [-]) of the friction law:
        slow sliding in contact then also shows the static friction
        (:func:`static_episodes`).

    """
    out = {}
    for key, least, unit, why, names in BODIES:
        travel = _travel(cols, key)
        if travel is not None and travel < least:
            for name in names:
                out[name] = f'{why} (it travelled {travel:.3g} {unit}, less than {least:g} {unit})'
    contact = np.asarray(cols['contact'])
    if len(np.unique(contact[contact != 0])) < 2:
        out['backlash'] = ('the load never reverses: the thread contact never changed '
                           'flank')
    if not len(static_episodes(cols, curve)):
        band = '' if curve is None else \
            f' nor slides in contact slower than {_slow_speed(curve):.3g} m/s'
        out['mu_s'] = (f'the motion never breaks away from standstill{band} (the static '
                       'friction acts nowhere else)')
    speed = np.abs(np.asarray(cols['sliding_velocity'], dtype=float))
    sliding = speed[speed > SLIDING]
    if not len(sliding):
        for name in ('mu_k',) + SHAPE:
            out[name] = 'the thread never slid'
        return out
    v = float(np.median(sliding))
    share = float(np.mean(np.abs(sliding - v) <= ONE_SPEED_BAND * v))
    if share >= ONE_SPEED_SHARE:
        for name in SHAPE:
            out[name] = (f'the thread slides at a single speed ({v:.3g} m/s in '
                         f'{100 * share:.3g} % of its sliding steps): the friction curve\'s '
                         'shape needs more than one')
    return out


def _travel(cols, key):
    """Return the path [unit of the rate x s] a body's rate column ``key`` covers, or None."""
    if key not in cols or 'time' not in cols or len(cols['time']) < 2:
        return None
    rate = np.abs(np.asarray(cols[key], dtype=float))
    dt = np.diff(np.asarray(cols['time'], dtype=float))
    return float(np.sum(rate[1:] * dt))


#: Least weight of the static friction in the Stribeck law, exp(-(v / v_s)^delta), at which
#: sliding in contact counts as showing it.
STATIC_WEIGHT = 0.05

#: Steps without a static-friction step that separate two episodes of :func:`static_episodes`.
EPISODE_GAP = 20


def _slow_speed(curve):
    """Return the sliding speed [m/s] below which mu_s weighs more than STATIC_WEIGHT."""
    v_s, delta = curve
    return float(v_s * np.log(1.0 / STATIC_WEIGHT) ** (1.0 / delta))


def static_episodes(cols, curve=None):
    """
    Return the (first, last) step of each episode of the compared run in which mu_s acts.

    The static friction acts where the thread breaks away from standstill
    (stuck, ``stick_a`` 1, then sliding) and, in the Stribeck law
    mu_k + (mu_s - mu_k) exp(-(v / v_s)^delta), wherever the thread slides
    in contact slower than the speed at which its weight falls to
    :data:`STATIC_WEIGHT` (``curve`` given): a start from rest whatever
    drives it (a torque step, a velocity step, a slow ramp), a start from
    the backlash gap (the thread reaches its flank with the nut at rest, as
    on a horizontal axis without load, where it is never stuck), a reversal
    and a stop. Steps closer than :data:`EPISODE_GAP` are one episode;
    indices are of the compared steps.
    """
    stick = np.asarray(cols['stick_a'])
    marks = np.zeros(len(stick), dtype=bool)
    marks[1:] |= (stick[:-1] == 1) & (stick[1:] == 0)
    if curve is not None and curve[0] > 0:
        speed = np.abs(np.asarray(cols['sliding_velocity'], dtype=float))
        contact = np.asarray(cols['contact']) != 0
        marks |= contact & (stick == 0) & (speed > SLIDING) & (speed < _slow_speed(curve))
    idx = np.flatnonzero(marks)
    if not len(idx):
        return []
    cut = np.flatnonzero(np.diff(idx) > EPISODE_GAP)
    firsts = np.r_[idx[0], idx[cut + 1]]
    lasts = np.r_[idx[cut], idx[-1]]
    return [(int(a), int(b)) for a, b in zip(firsts, lasts)]
