"""
Standard identification profiles of the axis: commands as functions of time (no ROS).

Four profiles, each an immutable object with a name, the command it uses, a
duration and its command values (``values(t)`` on numpy arrays, ``profile(t)``
on one time):

- ``breakaway``: a slow motor torque ramp [N m] from the centre torque past
  breakaway toward +theta and back, then toward -theta and back
  (``torque_command``);
- ``sweep``: a ladder of constant nut speeds [m/s], log-spaced from well below
  the Stribeck velocity to fast, in both directions, with the same travel back
  (``velocity_command``);
- ``reversals``: small back-and-forth moves of the nut position [m] with dwells,
  so the backlash shows (``position_command``);
- ``iso230``: bidirectional positioning in the style of ISO 230-2, linear test
  cycle: targets spread over a travel, each approached from below and from
  above with an overshoot, a dwell at each target, several cycles
  (``position_command``).

Every profile is a piecewise-linear sequence of :class:`Segment` s; the
options have units, defaults derived from the axis parameters (stroke, torque
and velocity limits, lead) and ranges, and a value outside them raises
:class:`ProfileError` naming the profile, the option, the value and what is
allowed. ``make_profile(name, params, **options)`` builds one; ``PROFILES``
maps the names to the classes. The command sense is the node's: torque in
the theta sense, nut velocity and position along +x.

The profiles live in :mod:`.breakaway`, :mod:`.sweep` and :mod:`.positioning`,
the broadband ones in :mod:`.broadband` and the chained run in :mod:`.commission`;
this module names them all.
"""
from .base import ProfileError, Segment
from .breakaway import BreakawayRamp, static_breakaway
from .commission import COMMISSION
from .positioning import Iso230, Reversals
from .singles import PROFILES
from .sweep import SpeedSweep

__all__ = ['ALL_PROFILES', 'PROFILES', 'ProfileError', 'Segment', 'make_profile', 'BreakawayRamp',
           'SpeedSweep', 'Reversals', 'Iso230', 'static_breakaway']

#: Every name ``make_profile`` builds: the single profiles and the chained commission run
#: (not a single profile: a part per command kind).
ALL_PROFILES = dict(PROFILES, **COMMISSION)


def make_profile(name, params, **options):
    """
    Return the profile ``name`` for the axis ``params`` with ``options``.

    Parameters
    ----------
    name : str
        A key of :data:`ALL_PROFILES` (a single profile, or ``commission``).
    params : ScrewParams
        The axis (stroke, limits, lead, initial position).
    **options
        Options of the profile (SI units); None keeps the default.

    """
    try:
        cls = ALL_PROFILES[name]
    except KeyError:
        raise ProfileError(name, 'name', '', f'unknown excitation profile {name!r} (profiles: '
                           f'{", ".join(ALL_PROFILES)})') from None
    return cls(params, **options)
