"""
The friction law of the thread contact (physics.md section 6), compiled.

mu_apparent is the plain Stribeck law on the parameter vector; _mu is the same
law on unpacked parameters with a bit-exact shortcut (_stribeck_cut gives where
it applies), and _mu_lower an exp-free lower bound of it. _thread_limit and
_thread_limits turn the law into the impulse limits of a thread for one substep.
"""
import math

from ._jit import kernel_jit
from .layout import P_DST, P_MUK, P_MUS, P_MUV, P_VST


@kernel_jit
def mu_apparent(P, v):
    """
    Apparent Stribeck friction coefficient mu'(|v|), >= 0, from the parameter vector.

    The plain formula of physics.md section 6; the kernel uses _mu, the same law
    with a bit-exact shortcut, tested against this one.
    """
    a = abs(v)
    mu = P[P_MUK] + P[P_MUV] * a
    drop = P[P_MUS] - P[P_MUK]
    if drop != 0.0:
        z = a / P[P_VST]
        if P[P_DST] != 1.0:
            z = z ** P[P_DST]
        mu += drop * math.exp(-z)
    return mu if mu > 0.0 else 0.0


@kernel_jit
def _mu(muk, muv, drop, vst, dst, zcut, v):
    """
    Apparent Stribeck coefficient mu'(|v|) >= 0 from unpacked parameters.

    The Stribeck term is skipped where it cannot change the sum: for
    |v| / v_st > zcut (see _stribeck_cut) and a sum not below mu_k, it is less
    than half an ulp of the sum, so the result is bit-identical to mu_apparent.
    """
    a = abs(v)
    mu = muk + muv * a
    if drop != 0.0:
        z = a / vst
        if z <= zcut or mu < muk:
            if dst != 1.0:
                z = z ** dst
            mu += drop * math.exp(-z)
    return mu if mu > 0.0 else 0.0


@kernel_jit
def _mu_lower(muk, muv, drop, ivst, dst, v):
    """
    Return a lower bound of _mu(v) without exp() or division: exp(-z) >= max(0, 1 - z).

    ivst = 1 / v_st. The 2e-15 |drop| margin (9 ulp) covers the rounding of
    1 - z and of the reciprocal against that of exp(-z) in _mu.
    """
    mu = muk + muv * abs(v)
    if drop > 0.0:
        z = abs(v) * ivst
        if dst == 1.0 and z < 1.0:
            mu += drop * (1.0 - z) - 2e-15 * drop
    elif drop < 0.0:
        mu += drop + 2e-15 * drop
    return mu


@kernel_jit
def _stribeck_cut(muk, drop, dst):
    """
    Return the |v| / v_st above which |drop| exp(-z) < mu_k 2**-54 (half an ulp of mu_k).

    37.5 > 54 ln 2 = 37.43; returns inf where no cut is safe (mu_k = 0).
    """
    if muk <= 0.0 or drop == 0.0:
        return math.inf
    zc = 37.5 + math.log(abs(drop) / muk)
    if zc <= 0.0:
        return 0.0
    return zc if dst == 1.0 else zc ** (1.0 / dst)


@kernel_jit
def _thread_limit(load, vs, muk, muv, drop, vst, dst, zcut, hcl):
    """Exact impulse limit [N s] of a thread: mu'(vs) load h / cos(lambda); hcl = h / cos."""
    return _mu(muk, muv, drop, vst, dst, zcut, vs) * load * hcl


@kernel_jit
def _thread_limits(load, mode, vs, muk, muv, drop, vst, ivst, dst, zcut, hcl, hcl_lo):
    """
    Return (limit, lower bound) [N s] of a thread's friction impulse.

    A thread warm-started stuck (mode 0) gets the exp-free lower bound only,
    and limit -1 (not computed yet): the bound confirms most sticks, with the
    very impulse of the exact solve. No load: (0, 0), the thread is inactive.
    """
    if load <= 0.0:
        return 0.0, 0.0
    if mode == 0:
        lo = _mu_lower(muk, muv, drop, ivst, dst, vs) * load * hcl_lo
        if lo > 0.0:
            return -1.0, lo
    return _thread_limit(load, vs, muk, muv, drop, vst, dst, zcut, hcl), 0.0
