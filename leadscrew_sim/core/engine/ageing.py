"""
The ageing of the axis (doc/model.md section 19), compiled: wear, lubricant, heat.

Three slow processes change the axis while it works. Each is integrated once
per step, after the substeps, from the step's last substep (rectangle rule):
their time scales (minutes to months) are far longer than a step.

- Flank wear (Archard): each flank of each nut body grows in depth by
  ``wear_rate`` N |v_s| dt, N its normal force [N] and v_s the thread sliding
  velocity [m/s]. A worn flank recedes by its depth: the kernel's flank law
  (stages.smooth_forces) takes each flank's half gap, half the backlash plus
  its wear. A single nut's backlash opens by the wear of both flanks. In a
  split nut the preloaded flanks' wear relaxes the spring by its stiffness;
  once the spring reaches its free length a tie (the spring's end of travel)
  holds the halves, and the backlash opens by the wear beyond f_p / k_p.
- Lubricant: L decays as exp(-s / lubricant_life), s the sliding distance of
  nut A's thread [m]; the thread's coefficients are mu = L mu_wet + (1 - L)
  mu_dry (friction.friction_constants_at).
- Heat: the screw is one thermal mass C [J/K] with a loss G [W/K] to the
  ambient. It takes ``heat_to_screw`` of the step's thread and bearing
  friction power P; over a step of constant P its temperature follows the
  exact first-order response, T - T_amb <- (T - T_amb) e + P (1 - e) / G,
  e = exp(-G dt / C). It grows by alpha (T - T_amb) (x - x_fixed) at x: the
  linear scale reads the grown position, the motor encoder does not.

``ageing_speedup`` multiplies the wear and lubricant rates and divides C; the
parameter vector holds the rates already scaled (pack_ageing). The ageing
state lives in S (S_WLA .. S_TEMP) and is kept by a reset; its outputs are
O_WLA .. O_GROW.
"""
import math

from ._jit import kernel_jit
from .friction import friction_constants_at, mixed_cut, wet_coefficients
from .layout import (
    O_BLASH, O_GROW, O_HEAT, O_LUB, O_MUK, O_MUS, O_PRELOAD, O_TEMP, O_WLA, O_WLB, O_WUA,
    O_WUB, P_ALPHA, P_AB, P_B, P_FP, P_H2S, P_HCAP, P_HLOSS, P_ILIFE, P_KP, P_MUKD, P_MUKDR,
    P_MUKW, P_MUSD, P_MUSDR, P_MUSW, P_TAMB, P_WEAR, P_XFIX, S_LUB, S_TEMP, S_WLA, S_WLB,
    S_WUA, S_WUB,
)


def pack_ageing(p, v):
    """Fill the ageing slots of the parameter vector v from ScrewParams p."""
    sp = p.ageing_speedup
    tf = p.thread_factor
    v[P_WEAR] = p.wear_rate * sp
    v[P_ILIFE] = sp / p.lubricant_life if p.lubricant_life > 0.0 else 0.0
    v[P_MUSD] = p.mu_s_dry * tf
    v[P_MUKD] = p.mu_k_dry * tf
    v[P_HCAP] = p.screw_heat_capacity / sp
    v[P_HLOSS] = p.screw_heat_loss
    v[P_TAMB] = p.ambient_temperature
    v[P_H2S] = p.heat_to_screw
    v[P_ALPHA] = p.thermal_expansion
    v[P_XFIX] = p.fixed_bearing_x
    v[P_MUSW] = p.mu_s
    v[P_MUKW] = p.mu_k
    v[P_MUSDR] = p.mu_s_dry
    v[P_MUKDR] = p.mu_k_dry


#: ageing_constants of an axis that does not age (every rate off): the same types.
NOT_AGEING = (False, False, False, False, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)


@kernel_jit
def aged(P, S):
    """
    Return True if the axis ages or has aged: a rate is on, or the state is not a new axis's.

    A new axis with every rate off (the default) skips the ageing's set-up in
    each call of the kernel: a one-step call pays nothing for it.
    """
    return (P[P_WEAR] > 0.0 or P[P_ILIFE] > 0.0 or P[P_HCAP] > 0.0 or S[S_LUB] != 1.0
            or S[S_WLA] != 0.0 or S[S_WUA] != 0.0 or S[S_WLB] != 0.0 or S[S_WUB] != 0.0
            or S[S_TEMP] != P[P_TAMB])


@kernel_jit
def ageing_constants(P, dt):
    """
    Return ac, the constants of the ageing for steps of dt [s].

    ac = (rates_on, wear_on, lub_on, heat_on, wear, ilife, decay, gain, t_amb,
    h2s, alpha, x_fix, zcut): some rate is on, and which; wear: scaled wear rate
    [m/(N m)]; ilife: scaled 1 / lubricant_life [1/m]; decay, gain: the
    temperature's step response, T - T_amb <- (T - T_amb) decay + P gain
    (gain [K/W]); t_amb [degC]; h2s: heat_to_screw; alpha [1/K]; x_fix [m];
    zcut: the Stribeck cut of any mix of wet and dry thread (friction.mixed_cut).
    """
    wear = P[P_WEAR]
    ilife = P[P_ILIFE]
    cap = P[P_HCAP]
    g = P[P_HLOSS]
    heat_on = cap > 0.0
    decay = 1.0
    gain = 0.0
    if heat_on:
        if g > 0.0:
            decay = math.exp(-g * dt / cap)
            gain = (1.0 - decay) / g
        else:
            gain = dt / cap
    wear_on = wear > 0.0
    lub_on = ilife > 0.0
    return (wear_on or lub_on or heat_on, wear_on, lub_on, heat_on, wear, ilife, decay, gain,
            P[P_TAMB], P[P_H2S], P[P_ALPHA], P[P_XFIX], mixed_cut(P, P[P_MUSD], P[P_MUKD]))


@kernel_jit
def flank_gaps(S, half_b):
    """
    Return wr = (hlo_a, hup_a, hlo_b, hup_b): each flank's half gap [m], half_b plus its wear.

    Unworn flanks give half_b itself (adding 0.0), so an axis without wear
    steps bit for bit as before the wear existed.
    """
    return (half_b + S[S_WLA], half_b + S[S_WUA], half_b + S[S_WLB], half_b + S[S_WUB])


@kernel_jit
def thread_constants(P, S, fc, ac):
    """
    Return the friction law's constants at the lubricant state of S.

    fc (the wet thread's) itself while the lubricant is fresh (L = 1), else
    friction.friction_constants_at the mixed coefficients, with the cut of
    ageing_constants ac.
    """
    lub = S[S_LUB]
    if lub == 1.0:
        return fc
    mus, muk = wet_coefficients(P)
    return friction_constants_at(fc, mus * lub + P[P_MUSD] * (1.0 - lub),
                                 muk * lub + P[P_MUKD] * (1.0 - lub), ac[12])


@kernel_jit
def growth_factor(S, ac):
    """Return alpha (T - T_amb): the screw's thermal strain [-] at the temperature of S."""
    return ac[10] * (S[S_TEMP] - ac[8])


@kernel_jit
def ageing_step(S, ac, nla, nua, nlb, nub, vs_a, vs_b, p_fric, dt):
    """
    Advance the ageing state of S by a step of dt [s]; return the heat flow [W].

    nla, nua, nlb, nub: flank normal forces of the step's last substep [N]
    (leading and trailing of nut A, then half-nut B); vs_a, vs_b: the
    threads' sliding velocities [m/s]; p_fric: the thread and bearing
    friction power [W]; ac: ageing_constants.
    """
    (_on, wear_on, lub_on, heat_on, wear, ilife, decay, gain, t_amb, h2s, _alpha,
     _x_fix, _zcut) = ac
    if wear_on:
        da = wear * abs(vs_a) * dt
        S[S_WLA] += da * nla
        S[S_WUA] += da * nua
        db = wear * abs(vs_b) * dt
        S[S_WLB] += db * nlb
        S[S_WUB] += db * nub
    if lub_on:
        S[S_LUB] *= math.exp(-ilife * abs(vs_a) * dt)
    heat = 0.0
    if heat_on:
        heat = h2s * p_fric
        S[S_TEMP] = t_amb + (S[S_TEMP] - t_amb) * decay + heat * gain
    return heat


@kernel_jit
def ageing_outputs(P, S, out, heat, grow, xa):
    """
    Write the ageing outputs O_WLA .. O_GROW of the state S into out.

    heat: the step's heat flow into the screw [W]; grow: alpha (T - T_amb);
    xa: nut A's position [m]. The coefficients are reported as set (not the
    apparent ones of the law), mixed as the law mixes them.
    """
    wla, wua, wlb, wub = S[S_WLA], S[S_WUA], S[S_WLB], S[S_WUB]
    out[O_WLA] = wla
    out[O_WUA] = wua
    out[O_WLB] = wlb
    out[O_WUB] = wub
    if P[P_AB] > 0.5:   # the preloaded flanks (A leading, B trailing) relax the spring first
        worn = wla + wub
        out[O_PRELOAD] = max(0.0, P[P_FP] - P[P_KP] * worn)
        out[O_BLASH] = max(0.0, worn - P[P_FP] / P[P_KP])
    else:
        out[O_PRELOAD] = 0.0
        out[O_BLASH] = P[P_B] + wla + wua
    lub = S[S_LUB]
    out[O_LUB] = lub
    out[O_MUK] = P[P_MUKW] * lub + P[P_MUKDR] * (1.0 - lub)
    out[O_MUS] = P[P_MUSW] * lub + P[P_MUSDR] * (1.0 - lub)
    out[O_TEMP] = S[S_TEMP]
    out[O_HEAT] = heat
    out[O_GROW] = grow * (xa - P[P_XFIX])
