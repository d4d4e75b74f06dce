"""Stage 'frequency response': the chirp's H1 over the twin's linear model, margins to Nyquist."""
import math
import os

import numpy as np

from ..trim import write_window
from ...freqresp.recording import recording_response, RecordingOptions
from ....analysis.freqresp.measure import linear_response
from ....analysis.freqresp.summary import bandwidth, margins, resonances
from ....core.drive_control import drive_period
from ....core.params import ParameterError

#: Points of the linear model's curves.
POINTS = 600
#: The linear model at rest with the thread's friction left out: the loops' highest gain
#: (a stuck thread holds the motor on the flank stiffness), so the smallest margins.
REST = 'free'
LINEAR_MODEL = ('linearised at rest with the thread friction left out (rest=free): the '
                'loops\' highest gain, so their smallest margins')


def run(ctx):
    """Return the frequency-response section (measured where the chirp is, else linear only)."""
    p = ctx.calibrated
    section = {'title': 'Frequency response', 'cannot': []}
    dt = 1.0 / float(ctx.rate)
    td = drive_period(p, dt) if p.drive_type == 'servo' else dt
    nyquist = 0.5 / td
    section['drive_nyquist_hz'] = nyquist
    meas = None
    if 'chirp' in ctx.windows:
        a, b = ctx.windows['chirp']
        path = os.path.join(ctx.work, 'chirp_window.mcap')
        write_window(ctx.rec, path, ctx.origin + b, ctx.origin + a)
        meas = recording_response(path, RecordingOptions(
            input='velocity_command', output='motor_velocity', **ctx.axis.response_options))
        ok = meas.coherence >= 0.9
        section['measured'] = {'frequency': meas.frequency.tolist(),
                               'magnitude_db': meas.magnitude_db.tolist(),
                               'phase_deg': meas.phase_deg.tolist(),
                               'coherence': meas.coherence.tolist(),
                               'coherent_band_hz': ([float(meas.frequency[ok].min()),
                                                     float(meas.frequency[ok].max())]
                                                    if ok.any() else None)}
    else:
        section['cannot'].append('no chirp segment: no measured response; the curves are the '
                                 'calibrated twin\'s linear model only')
    if p.drive_type != 'servo':
        section['cannot'].append('a stepper has no linear model of its drive: no loop margins')
        return section
    fmin = float(meas.frequency[meas.frequency > 0].min()) if meas is not None else 0.5
    f = np.geomspace(min(fmin, 1.0), 0.999 * nyquist, POINTS)
    try:
        lin = linear_response(p, 'velocity_command', 'motor_velocity', frequency=f,
                              sampling='step', dt=dt, rest=REST)
    except (ParameterError, ValueError) as exc:
        section['cannot'].append(f'the linear model does not exist here: {exc}')
        return section
    section['linear'] = {'frequency': f.tolist(), 'magnitude_db': lin.magnitude_db.tolist(),
                         'phase_deg': lin.phase_deg.tolist()}
    res, anti = resonances(lin)
    section['resonances'] = [{'frequency': fn, 'damping': z} for fn, z in res]
    section['antiresonances'] = [{'frequency': fn, 'damping': z} for fn, z in anti]
    bw = bandwidth(lin)
    section['bandwidth_hz'] = bw if math.isfinite(bw) else None
    if not math.isfinite(bw):
        section['cannot'].append('the -3 dB bandwidth lies beyond the band up to Nyquist')
    section['loops'] = {}
    fl = np.geomspace(0.1, 0.4999 / td, 4000)
    for loop in ('velocity', 'position'):
        L = linear_response(p, loop=loop, quantity='L', sampling='drive', frequency=fl,
                            dt=dt, rest=REST)
        mg = margins(fl, L.loop_gain)
        section['loops'][loop] = {k: (float(v) if v is not None and math.isfinite(v) else None)
                                  for k, v in mg.items() if isinstance(v, (int, float))}
        for k, v in section['loops'][loop].items():
            if v is None:
                section['cannot'].append(f'{loop} loop {k}: no crossing below the drive\'s '
                                         'Nyquist frequency')
    section['linear_model'] = LINEAR_MODEL
    if not p.mu_s == 0.0:
        section['cannot'].append('the linear model leaves the thread friction out; the chirp '
                                 'about zero speed sticks at each reversal, so below a few hertz '
                                 'the measured H1 (a describing function) and its coherence '
                                 'fall away from it')
    return section
