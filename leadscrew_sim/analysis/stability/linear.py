"""
Linear stability of steady sliding: growth rate, frequency and mechanism.

:func:`linear_stability` classifies by the rule of doc/stability.md, in this order:
kinematic_constraint (the rigid-contact effective inertia J_e <= 0), stable
(no eigenvalue's real part above NEUTRAL times the largest
eigenvalue modulus: an undamped, neutral mode counts as stable, round-off
aside), mode_coupling (still unstable with
the friction slope set to 0), negative_damping (otherwise).
"""
import math

import numpy as np

from .linearise import eigenvalues
from .operating_point import operating_point

__all__ = ['least_stable', 'linear_stability', 'MECHANISMS']

#: Relative round-off band of a neutral eigenvalue's real part [-].
NEUTRAL = 1e-9

#: The mechanism labels of the CSV column ``mechanism``.
MECHANISMS = ('stable', 'negative_damping', 'mode_coupling', 'kinematic_constraint')


def least_stable(eigs):
    """
    Return (growth rate [1/s], frequency [Hz]) of the eigenvalue with the largest real part.

    Parameters
    ----------
    eigs : numpy.ndarray
        Eigenvalues [1/s].

    """
    k = int(np.argmax(eigs.real))
    return float(eigs[k].real), float(abs(eigs[k].imag) / (2.0 * math.pi))


def linear_stability(params, speed, drive='velocity'):
    """
    Return the linear stability of steady sliding at nut speed ``speed``.

    Parameters
    ----------
    params : ScrewParams
        The axis (single nut).
    speed : float
        Nut speed [m/s], nonzero; sign = direction along +x.
    drive : str
        'velocity' (the servo's velocity loop, as a continuous PI) or 'ideal'
        (prescribed motor angle).

    Returns
    -------
    dict
        growth_rate [1/s] (largest real part), frequency [Hz] (of that mode),
        mechanism (one of MECHANISMS), effective_inertia J_e [kg m^2], and the
        operating point's mu0, slope [s/m], N0 [N], torque [N m] (q sense).

    Raises
    ------
    ParameterError
        If the operating point does not exist (see operating_point).

    """
    op = operating_point(params, speed, drive)
    eigs = eigenvalues(op, params)
    growth, freq = least_stable(eigs)
    if not (math.isfinite(growth) and math.isfinite(freq)):
        raise ValueError(f'speed: the linearisation at {speed!r} m/s is not finite')
    if op['J_e'] <= 0.0:
        mech = 'kinematic_constraint'
    elif growth <= NEUTRAL * np.abs(eigs).max():
        mech = 'stable'
    else:
        e0 = eigenvalues(op, params, slope=0.0)
        g0, _ = least_stable(e0)
        mech = 'mode_coupling' if g0 > NEUTRAL * np.abs(e0).max() else 'negative_damping'
    return dict(growth_rate=growth, frequency=freq, mechanism=mech,
                effective_inertia=op['J_e'], mu0=op['mu0'], slope=op['slope'],
                N0=op['N0'], torque=op['torque'])
