"""Stage 'twin': the calibrated stand-in re-simulating the recording, judged on held-out parts."""
import numpy as np

from ...replay.resim import Resim
from ....io.run_file import PARAMS_RECORD, params_from_record
from ....core.params import ScrewParams

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
#: The sensor settings the twin takes from the recording (the axis's own sensors).
SENSORS = ('encoder_counts', 'encoder_noise', 'encoder_bias', 'scale_resolution',
           'scale_noise', 'scale_bias', 'sensor_seed', 'linear_scale')


def calibrated_overrides(params, recorded):
    """
    Return every physics value of the calibrated ``params``, the sensors as ``recorded``.

    The drive's loops act on the sensor readings: the twin reads the axis's
    sensors with their recorded settings (their noise seed too), so the
    loops see the same noise as on the recording.
    """
    values = {n: getattr(params, n) for n in ScrewParams.names() if not n.startswith('fault_')}
    values.update({n: getattr(recorded, n) for n in SENSORS if hasattr(recorded, n)})
    return values


def run(ctx):
    """Re-simulate the whole recording with the calibrated set; return the held-out section."""
    section = {'title': 'The twin against the recording', 'parts': {}, 'cannot': []}
    recorded, _missing = params_from_record(ctx.rec.record(PARAMS_RECORD))
    sim = Resim(ctx.rec, calibrated_overrides(ctx.calibrated, recorded))
    cols = sim.replay()
    ctx.twin = cols
    ctx.twin_time = (sim.t0 + (np.arange(len(cols['nut_position'])) + 1) * sim.dt_ns) / 1e9
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
    if recorded.drive_type == 'stepper' and not recorded.encoder_counts and \
            not recorded.linear_scale:
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
                          'the measured reading less the twin\'s true nut position')
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
    rms = section['held_out']['rms_um']
    section['sentence'] = (f'the stand-in reproduces this axis to {rms:.3g} um RMS on data it '
                           'was not fitted to')
    return section


def _stats(e, sigma):
    rms, mx = float(np.sqrt(np.mean(e * e))), float(np.max(np.abs(e)))
    out = {'rms_um': rms * 1e6, 'max_um': mx * 1e6, 'samples': int(len(e))}
    if sigma:
        out.update(rms_over_noise=rms / sigma, max_over_noise=mx / sigma)
    return out
