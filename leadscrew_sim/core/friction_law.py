"""
The thread's friction law as numbers: mu'(v) and its slope dmu'/dv, as the kernel applies them.

For analyses that linearise the model about steady sliding (the stability
of steady sliding): the same compiled law as the kernel's, on the packed
parameters, so a linearisation and a simulation never use two laws.
"""
import math

from .engine.friction import friction_constants, mu_apparent
from .engine.packing import pack_params

__all__ = ['FrictionLaw']


class FrictionLaw:
    """
    The apparent friction coefficient mu' (thread angle included) of an axis against speed.

    Parameters
    ----------
    params : ScrewParams
        The axis.

    """

    def __init__(self, params):
        """Pack the parameters the law reads."""
        self._P = pack_params(params)

    def mu(self, v):
        """
        Return mu'(|v|) [-], as the kernel's sliding friction applies it.

        Parameters
        ----------
        v : float
            Sliding speed [m/s].

        """
        return mu_apparent(self._P, abs(v))

    def slope(self, v):
        """
        Return dmu'/dv [s/m] at the speed |v| > 0; 0 where the law clips at 0.

        The derivative of mu'(v) = mu_k' + (mu_s' - mu_k') exp(-(v/v_st)^d) + mu_v' v.

        Parameters
        ----------
        v : float
            Sliding speed [m/s].

        """
        a = abs(v)
        if mu_apparent(self._P, a) <= 0.0:
            return 0.0
        _, muv, drop, vst, _, dst, _ = friction_constants(self._P)
        slope = muv
        if drop != 0.0:
            z = a / vst
            slope -= drop * dst * z ** (dst - 1.0) / vst * math.exp(-z ** dst)
        return slope
