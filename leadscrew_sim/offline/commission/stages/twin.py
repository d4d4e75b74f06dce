"""Stage 'twin': the calibrated stand-in re-simulating the recording, judged on held-out parts."""
import numpy as np


#: Parts the fit did not see whose nut position the drive controls, compared in this order.
#: The breakaway is torque-driven: its nut position integrates any torque difference (the
#: friction section compares its breakaway torques instead).
HELD_OUT = ('reversals', 'iso230')
#: Parts after the sweep whose nut position the drive does not hold (torque or speed
#: commands): their error integrates the friction's difference; listed, not the headline.
DRIFTING = ('breakaway', 'chirp')
#: Start of each held-out part left out [s]: the twin enters it from its own end state of
#: the part before (a torque- or speed-driven one), and the position loop pulls both onto
#: the first target within it.
SETTLE = 0.5
#: The sensor settings whose noise is drawn from the sensor seed.
NOISY = ('encoder_noise', 'scale_noise')
#: Twins of other sensor seeds whose spread gives the closed loop's noise floor.
DRAWS = 3


def run(ctx):
    """Re-simulate the whole recording with the calibrated set; return the held-out section."""
    section = {'title': 'The twin against the recording', 'parts': {}, 'cannot': []}
    cols, t = ctx.axis.resimulate(ctx.calibrated, ctx.fit)
    ctx.twin, ctx.twin_time = cols, t - ctx.origin
    held = [p for p in HELD_OUT if p in ctx.windows] if ctx.fit else []
    sigma = ctx.noise.get('nut_position')
    section['noise_um'] = None if sigma is None else sigma * 1e6
    m = ctx.measured
    errs = []
    section['drifting'] = {}
    for part in held + [p for p in DRIFTING if p in ctx.windows]:
        a, b = ctx.windows[part]
        mask = m.window(a + (SETTLE if part in held else 0.0), b)
        if not mask.any():
            continue
        meas = m.nut_position[mask]
        twin = np.interp(m.time[mask], ctx.twin_time, cols['nut_position'])
        e = meas - twin
        if part in held:
            errs.append(e)
            section['parts'][part] = dict(_stats(e, sigma), window=[a + SETTLE, b])
        else:
            section['drifting'][part] = dict(_stats(e, sigma), window=[a, b])
    if not ctx.fit:
        section['cannot'].append('nothing was fitted (no sweep): there is no calibrated twin '
                                 'to judge on held-out data')
        return section
    if ctx.axis.stepper_unmeasured():
        section['cannot'].append('a stepper without encoder or linear scale reports its '
                                 'commanded steps as the nut position: the nut is not '
                                 'measured, so the twin cannot be judged against it')
        section['parts'], section['drifting'] = {}, {}
        return section
    if not errs:
        section['cannot'].append('no position-controlled part after the sweep (reversals, '
                                 'iso230): no held-out data whose position the drive holds, so '
                                 'how well the twin predicts cannot be told')
        return section
    section['sensors'] = ('the twin reads the recorded sensor settings (noise seed '
                          'included), so its drive loops see the recorded noise; the error is '
                          'the measured reading less the twin\'s true nut position'
                          if not ctx.axis.foreign else
                          'the twin reads sensors of the noise and resolution identify found '
                          '(their noise is not the axis\'s own draw), so its drive loops see '
                          'noise like the recorded; the error is the measured reading less '
                          'the twin\'s true nut position')
    section['held_out'] = _stats(np.concatenate(errs), sigma)
    if not sigma:
        section['cannot'].append('the nut position has no noise level here (identify did not '
                                 'compare it): the error is not given as a multiple of it')
    if section['drifting']:
        section['cannot'].append(
            f'{", ".join(section["drifting"])}: torque- or speed-commanded, the nut position '
            'there integrates every difference of friction, so its error says how far the '
            'position drifts, not how well the twin reproduces the axis')
    section['held_out_parts'] = held
    h = section['held_out']
    rms = h['rms_um']
    section['sentence'] = (f'the stand-in reproduces this axis to {rms:.3g} um RMS on data it '
                           'was not fitted to')
    spread = draw_spread(ctx, held)
    if spread is not None:
        floor = float(np.hypot(spread, sigma or 0.0))
        h.update(draw_spread_um=spread * 1e6, floor_um=floor * 1e6,
                 rms_over_floor=rms * 1e-6 / floor if floor > 0 else None)
        section['floor'] = ('the drive closes its loops over noisy sensors, so where the '
                            'thread sticks and slips at each target depends on the noise '
                            'drawn: twins that differ in their sensor noise alone differ '
                            f'by {spread * 1e6:.3g} um RMS on these parts; with the reading\'s '
                            f'own noise that is a floor of {floor * 1e6:.3g} um, which no twin '
                            'can beat on a recording of other noise')
        section['sentence'] += (f' ({rms * 1e-6 / floor:.2f} times the closed loop\'s noise '
                                f'floor of {floor * 1e6:.3g} um)')
    return section


def draw_spread(ctx, held):
    """
    Return the RMS difference [m] of twins differing in their noise draw alone, on ``held``.

    The calibrated set re-simulated with :data:`DRAWS` other sensor seeds,
    the RMS over every pair's difference; None when the twin's sensors have
    no noise (nothing is drawn).
    """
    values = ctx.axis.twin_values(ctx.calibrated, ctx.fit)
    if not any(values.get(n) for n in NOISY):
        return None
    seed = int(values.get('sensor_seed', 0))
    m = ctx.measured
    t = np.concatenate([m.time[m.window(ctx.windows[p][0] + SETTLE, ctx.windows[p][1])]
                        for p in held]) if held else np.empty(0)
    if not len(t):
        return None
    xs = []
    for i in range(1, DRAWS + 1):
        cols, tt = ctx.axis.resimulate(ctx.calibrated, ctx.fit, seed=seed + i)
        xs.append(np.interp(t, tt - ctx.origin, cols['nut_position']))
    d = np.concatenate([xs[i] - xs[j] for i in range(DRAWS) for j in range(i + 1, DRAWS)])
    return float(np.sqrt(np.mean(d * d)))


def _stats(e, sigma):
    rms, mx = float(np.sqrt(np.mean(e * e))), float(np.max(np.abs(e)))
    out = {'rms_um': rms * 1e6, 'max_um': mx * 1e6, 'samples': int(len(e))}
    if sigma:
        out.update(rms_over_noise=rms / sigma, max_over_noise=mx / sigma)
    return out
