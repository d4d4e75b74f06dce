"""
The friction law of the thread contact (doc/model.md section 6), compiled.

The law is self-contained: the kernel never names its parameters. They live
in the friction block of the parameter vector (N_FRICTION slots from
layout.P_FRICTION), whose slots this module alone assigns (P_MUS .. P_ZCUT
below). pack_friction (plain Python, called by packing.pack_params) fills them
from ScrewParams. friction_constants(P), called by the kernel once per call,
returns the law's constants as the tuple fc, forming drop = mu_s' - mu_k' and
ivst = 1 / v_st from the slots; the law functions take fc.

mu_apparent is the plain Stribeck law on the parameter vector; _mu is the same
law with a bit-exact shortcut (_stribeck_cut gives where it applies), and
_mu_lower an exp-free lower bound of it. _thread_limit and _thread_limits turn
the law into the impulse limits of a thread for one substep.

A new friction law (another curve shape, more parameters) therefore touches
this module and params.py (its fields) only, plus layout.py if its slots
outgrow the N_FRICTION of the block.
"""
import math

from ._jit import kernel_jit
from .layout import N_FRICTION, P_FRICTION

# Slots of the friction block in P ----------------------------------------------
P_MUS = P_FRICTION      # apparent (thread-form corrected) static coefficient mu_s' [-]
P_MUK = P_FRICTION + 1  # apparent kinetic coefficient mu_k' [-]
P_VST = P_FRICTION + 2  # Stribeck velocity v_st [m/s]
P_DST = P_FRICTION + 3  # Stribeck exponent delta_st [-]
P_MUV = P_FRICTION + 4  # apparent viscous slope mu_v' [s/m]
P_ZCUT = P_FRICTION + 5  # Stribeck cut-off in units of |v| / v_st [-], see _stribeck_cut
N_SLOTS = 6             # slots used; the rest of the block is spare
assert N_SLOTS <= N_FRICTION, 'the friction law outgrew layout.N_FRICTION'


def pack_apparent(v, mu_s, mu_k, mu_v, v_st, delta_st):
    """
    Fill the friction block of the parameter vector v from the law's coefficients.

    mu_s, mu_k, mu_v are the apparent (thread-form corrected) ones, mu'.
    """
    v[P_MUS] = mu_s
    v[P_MUK] = mu_k
    v[P_VST] = v_st
    v[P_DST] = delta_st
    v[P_MUV] = mu_v
    v[P_ZCUT] = _stribeck_cut(v[P_MUK], v[P_MUS] - v[P_MUK], v[P_DST])


def pack_friction(p, v):
    """Fill the friction block of the parameter vector v from ScrewParams p."""
    tf = p.thread_factor
    pack_apparent(v, p.mu_s * tf, p.mu_k * tf, p.mu_viscous * tf, p.stribeck_velocity,
                  p.stribeck_exponent)


@kernel_jit
def friction_constants(P):
    """
    Return the law's constants fc = (muk, muv, drop, vst, ivst, dst, zcut) from P.

    drop = mu_s' - mu_k' and ivst = 1 / v_st [s/m]; the others are the slots.
    """
    muk = P[P_MUK]
    muv = P[P_MUV]
    drop = P[P_MUS] - P[P_MUK]
    vst = P[P_VST]
    dst = P[P_DST]
    zcut = P[P_ZCUT]
    ivst = 1.0 / vst
    return (muk, muv, drop, vst, ivst, dst, zcut)


@kernel_jit
def wet_coefficients(P):
    """Return (mu_s', mu_k'): the apparent coefficients of the block (the lubricated thread)."""
    return P[P_MUS], P[P_MUK]


@kernel_jit
def mixed_cut(P, mus_dry, muk_dry):
    """
    Return a Stribeck cut (see _stribeck_cut) that holds for every mix of wet and dry thread.

    The coefficients of a mix, L wet + (1 - L) dry, move linearly in L, so
    |drop| / mu_k is monotone in L between its ends and its largest cut is at
    one of them. A cut above a mix's own only evaluates exp where the term
    is below half an ulp, so the law's values are the same bits.
    """
    dst = P[P_DST]
    return max(P[P_ZCUT], _stribeck_cut(muk_dry, mus_dry - muk_dry, dst))


@kernel_jit
def friction_constants_at(fc, mus, muk, zcut):
    """
    Return the law's constants fc with the apparent coefficients mus, muk and the cut zcut.

    The lubricant of ageing.py moves the coefficients between the wet and
    the dry thread; zcut is mixed_cut's.
    """
    return (muk, fc[1], mus - muk, fc[3], fc[4], fc[5], zcut)


@kernel_jit
def mu_apparent(P, v):
    """
    Apparent Stribeck friction coefficient mu'(|v|), >= 0, from the parameter vector.

    The plain formula of doc/model.md section 6; the kernel uses _mu, the same law
    with a bit-exact shortcut, tested against this one.
    """
    muk, muv, drop, vst, _, dst, _ = friction_constants(P)
    a = abs(v)
    mu = muk + muv * a
    if drop != 0.0:
        z = a / vst
        if dst != 1.0:
            z = z ** dst
        mu += drop * math.exp(-z)
    return mu if mu > 0.0 else 0.0


@kernel_jit
def _mu(fc, v):
    """
    Apparent Stribeck coefficient mu'(|v|) >= 0 from the law's constants fc.

    The Stribeck term is skipped where it cannot change the sum: for
    |v| / v_st > zcut (see _stribeck_cut) and a sum not below mu_k, it is less
    than half an ulp of the sum, so the result is bit-identical to mu_apparent.
    """
    muk, muv, drop, vst, _, dst, zcut = fc
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
def _mu_lower(fc, v):
    """
    Return a lower bound of _mu(fc, v) without exp() or division: exp(-z) >= max(0, 1 - z).

    It uses ivst = 1 / v_st. The 2e-15 |drop| margin (9 ulp) covers the
    rounding of 1 - z and of the reciprocal against that of exp(-z) in _mu.
    """
    muk, muv, drop, _, ivst, dst, _ = fc
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
def _thread_limit(load, vs, fc, hcl):
    """Exact impulse limit [N s] of a thread: mu'(vs) load h / cos(lambda); hcl = h / cos."""
    return _mu(fc, vs) * load * hcl


@kernel_jit
def _thread_limits(load, mode, vs, fc, hcl, hcl_lo):
    """
    Return (limit, lower bound) [N s] of a thread's friction impulse.

    A thread warm-started stuck (mode 0) gets the exp-free lower bound only,
    and limit -1 (not computed yet): the bound confirms most sticks, with the
    very impulse of the exact solve. No load: (0, 0), the thread is inactive.
    """
    if load <= 0.0:
        return 0.0, 0.0
    if mode == 0:
        lo = _mu_lower(fc, vs) * load * hcl_lo
        if lo > 0.0:
            return -1.0, lo
    return _thread_limit(load, vs, fc, hcl), 0.0
