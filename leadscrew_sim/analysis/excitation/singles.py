"""The single excitation profiles by name: the parts of a chained run (:mod:`.commission`)."""
from .breakaway import BreakawayRamp
from .broadband import BROADBAND
from .positioning import Iso230, Reversals, Warmup
from .sweep import SpeedSweep

__all__ = ['PROFILES']

#: Profile name -> class: the single profiles and the broadband ones.
PROFILES = dict({cls.name: cls for cls in (BreakawayRamp, SpeedSweep, Reversals, Iso230, Warmup)},
                **BROADBAND)
