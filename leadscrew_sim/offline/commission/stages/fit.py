"""Stage 'identify': the friction fitted on the recording up to the end of its sweep."""
import math
import os
import time

from ..trim import write_window
from ...identify.run import fit_recording
from ....core.params import ScrewParams

#: What the sweep determines: the thread's friction curve (mu_s, mu_k, Stribeck velocity).
FIT = ('mu_s', 'mu_k', 'stribeck_velocity')


class StageLines:
    """identify's progress as one line per fit stage on ``say`` (wall time, re-simulations)."""

    def __init__(self, say):
        """Start the clock."""
        self.say, self.stage, self.t0 = say, None, time.perf_counter()

    def update(self, stage, evaluations, rms):
        """Say the stage when it changes (identify's FitProgress interface)."""
        if stage != self.stage:
            self.stage = stage
            self.say(f'commission:   identify: {stage} at {time.perf_counter() - self.t0:.1f} s, '
                     f'{evaluations} re-simulations')

    def done(self):
        """Say nothing more."""


def run(ctx, say=None):
    """Fit :data:`FIT` on the recording up to the sweep's end; return the report section."""
    section = {'title': 'Calibrated parameters', 'fitted': FIT, 'parameters': [],
               'cannot': []}
    sweep = ctx.windows.get('sweep')
    if sweep is None:
        ctx.calibrated = ctx.start
        section['cannot'].append('no sweep segment: nothing was fitted; the twin uses the '
                                 f'starting values of {ctx.label}')
        return section
    path = os.path.join(ctx.work, 'fit_window.mcap')
    write_window(ctx.rec, path, ctx.origin + sweep[1])
    args = ctx.identify_args
    args.file, args.fit = path, ','.join(FIT)
    out = fit_recording(args, None if say is None else StageLines(say))
    ctx.fit = out
    res = out['res']
    ctx.calibrated = ScrewParams.from_dict(
        {n: v for n, v, vd in zip(res.names, res.values, res.verdicts) if vd.identified},
        base=ctx.start)
    ctx.noise = {name: float(v[0]) for name, v in out['problem'].noise.items()}
    ctx.fitted_on = [f'recording from 0 to {sweep[1]:.3f} s (the sweep and the rest before it)']
    section['window'] = [0.0, sweep[1]]
    section['fit_wall_s'] = out['wall']
    section['rms_over_noise'] = {n: float(r) for n, r in zip(
        out['problem'].measurements.names, res.rms)}
    for i, name in enumerate(res.names):
        vd = res.verdicts[i]
        row = {'name': name, 'start': res.initial[i],
               'value': res.values[i] if vd.identified else None,
               'lower': _num(vd.lower) if vd.identified else None,
               'upper': _num(vd.upper) if vd.identified else None,
               'verdict': vd.status if vd.identified else 'not identified',
               'reason': getattr(vd, 'reason', '') or ''}
        section['parameters'].append(row)
        if not vd.identified:
            section['cannot'].append(f'{name}: {" ".join(str(row["reason"]).split())}')
    section['correlation'] = [[_num(x) for x in row] for row in res.correlation.tolist()]
    section['not_fitted'] = ('every other parameter keeps its starting value from '
                             f'{ctx.label}: this recording was not used to determine it')
    return section


def _num(x):
    """Return a float, or None for NaN (JSON has no NaN)."""
    x = float(x)
    return x if math.isfinite(x) else None
