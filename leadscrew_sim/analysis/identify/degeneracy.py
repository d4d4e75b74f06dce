"""
What a motion cannot show: the parameters a re-simulated run leaves undetermined, and why.

Some parameters act only through an event or a range of the motion: the
backlash only when the thread contact changes flank (a reversal of the
load), the static friction only when the thread breaks away from
standstill, the kinetic friction only while it slides, and the shape of
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


def motion_degeneracies(cols):
    """
    Return name -> why the motion of re-simulated columns ``cols`` cannot determine it.

    Parameters
    ----------
    cols : dict
        ``model.run`` columns of the steps compared: ``contact`` (the thread
        flank, 0 when none), ``stick_a`` (1 while stuck), ``sliding_velocity``
        [m/s].

    """
    out = {}
    contact = np.asarray(cols['contact'])
    if len(np.unique(contact[contact != 0])) < 2:
        out['backlash'] = ('the load never reverses: the thread contact never changed '
                           'flank')
    stick = np.asarray(cols['stick_a'])
    if not np.count_nonzero((stick[:-1] == 1) & (stick[1:] == 0)):
        out['mu_s'] = 'the motion never breaks away from standstill'
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
