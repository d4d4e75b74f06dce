"""
The report of ``identify``: the fit of a recording as text.

The verb prints it (unless ``--quiet``) and ``--report`` writes it to a file.
"""
import numpy as np

from ..offline.foreign.forces import forces_text
from ..offline.options import option_text
from ..analysis.identify.fit import LEVEL
from ..offline.identify.run import SHIFT
from ..core.params import ScrewParams

_UNITS = {n: md['unit'] for n, (_t, _d, md) in ScrewParams.field_info().items()}


def _g(v):
    """Return a float in 6 significant digits ('-' for NaN)."""
    return '-' if v != v else f'{v:.7g}'


def _static(episodes, most=8):
    """Return the line naming the segments [s] of the run that carry mu_s."""
    if not episodes:
        return ('mu_s is carried by no segment: the thread never breaks away from standstill '
                'nor slides slowly in contact in the steps compared')
    shown = ', '.join(f'{a:.3f}-{b:.3f} s' for a, b in episodes[:most])
    more = f' and {len(episodes) - most} more' if len(episodes) > most else ''
    return (f'mu_s is carried by {len(episodes)} segments of breakaway from standstill or slow '
            f'sliding in contact: {shown}{more}')


def report(path, out, name_of=None):
    """
    Return the report of a fit as text.

    Parameters
    ----------
    path : str
        The recording.
    out : dict
        What :func:`leadscrew_sim.offline.identify.run.fit_recording` returned.
    name_of : callable, optional
        ``name_of(keyword)``: the name of an option the report names (default
        its keyword; the verb gives its flags).

    """
    problem, res = out['problem'], out['res']
    meas = problem.measurements
    lines = [f'identify {path}: {problem.n} steps of {problem.dt * 1e3:g} ms '
             f'({problem.n * problem.dt:g} s), drive modes: {", ".join(problem.mode_names)}; '
             f'starting and fixed values from {out["label"]}',
             f'fitted against: {", ".join(meas.names)} (re-simulated without sensor noise '
             'and quantisation; each position signal with a free offset)']
    if problem.foreign:
        if problem.source.forces is not None:
            lines.append(forces_text(problem.source.forces).rstrip('; ')
                         + ', held on the twin\'s nut as the node holds it')
        delay = problem.source.delay
        lines.append(delay.line().replace('<<command_delay>> sets it', 'the mapping sets it')
                     if delay.how == 'set' else delay.line())
        if problem.fit_delay:
            lines.append(f'  fitted with the parameters: {problem.delay * 1e3:.3f} ms (each '
                         f're-simulation aligned in time to the states within '
                         f'+-{problem.shift_range * 1e3:.3g} ms of the delay above)')
    if getattr(problem, 'exact', False):
        lines.append('exact data (ideal sensors): no statistical intervals; each noise level '
                     'is the numerical floor, and a parameter that changes the signals by more '
                     'than it is fitted ("exact data"), not called identified')
    if getattr(problem, 'slow', 0):
        lines.append(f'left out: {problem.slow} steps of a commanded speed below '
                     'the encoder\'s velocity quantum through the drive period times 3 (the '
                     'drive\'s limit cycle there is not in the re-simulation)')
    if getattr(problem, 'anchoring', None) is not None:
        used = int(np.count_nonzero(meas.mask.any(axis=0)))
        why = ' (one run from the start did not explain the recording)' \
            if out.get('single') is not None else ''
        lines.append(f'restarted at {len(problem.anchoring.rests)} rests from the recorded '
                     f'state{why}; compared: {used} of {problem.n} steps, those the '
                     'recorded states determine to within the noise')
    if out.get('second') is not None:
        lines.append('fitted twice: the first fit did not explain the recording; the second, '
                     'its later scans also from the starting values, '
                     + ('did and replaced it' if out['second'] else 'did not either'))
    if out.get('shifted') is not None:
        tries, explained = out['shifted']
        lines.append(f'fitted from {tries} shifted start{"s" * (tries > 1)} (every fitted '
                     f'parameter {100 * SHIFT:g} % up, then down): '
                     + ('the last explained the recording and replaced the fit' if explained
                        else 'none explained the recording'))
    if out.get('loop_at_fit') is not None:
        grown, explained = out['loop_at_fit']
        lines.append('the drive loop\'s response to the sensors, measured again at the rejected '
                     f'fit, raised the noise level of {", ".join(grown)}; fitted again from the '
                     'start with it: ' + ('explained the recording and replaced the fit'
                                          if explained else 'did not explain it either'))
    if out.get('on_compared') is not None:
        fell, explained = out['on_compared']
        lines.append('the drive loop\'s response to the sensors, measured over the steps '
                     f'compared only, lowered the noise level of {", ".join(fell)}; fitted '
                     'again from the start with it and judged against it: '
                     + ('explained the recording and replaced the fit' if explained
                        else 'did not explain it either'))
    lines.append('')
    pct = int(round(100 * LEVEL))
    lines.append(f'{"parameter":<20} {"unit":<8} {"start":>13} {"value":>13} '
                 f'{f"{pct} % interval":>29}  verdict')
    for name, v0, v, lo, hi, vd in zip(res.names, res.initial, res.values, res.lower,
                                       res.upper, res.verdicts):
        ci = f'[{_g(lo)}, {_g(hi)}]' if vd.identified else '-'
        value = _g(v) if vd.fitted else f'({_g(v)})'
        lines.append(f'{name:<20} {_UNITS[name]:<8} {_g(v0):>13} {value:>13} {ci:>29}  '
                     f'{vd.status}')
    lines.append('')
    lines.append('verdicts:')
    for vd in res.verdicts:
        kept = '' if vd.fitted else ' (kept at its starting value)'
        lines.append(f'  {vd.name}: {vd.reason}{kept}')
    for note in getattr(problem, 'conditions', None) or []:
        lines.append(f'  {note}')
    if 'mu_s' in res.names and getattr(problem, 'static', None) is not None:
        lines.append('  ' + _static(problem.static))
    fitted = [i for i, vd in enumerate(res.verdicts) if vd.identified]
    if len(fitted) > 1:
        lines += ['', 'correlation of the identified parameters:']
        head = ' ' * 20 + ''.join(f'{res.names[j][:9]:>10}' for j in fitted)
        lines.append(head)
        for i in fitted:
            cells = ''.join(f'{res.correlation[i, j]:>+10.3f}' for j in fitted)
            lines.append(f'{res.names[i]:<20}{cells}')
    lines += ['', f'{"signal":<14} {"unit":<5} {"noise sigma":>12} {"rms start":>12} '
              f'{"rms fitted":>12} {"rms/sigma":>10}  sigma from']
    rms0, rms1 = meas.rms(out['initial']), meas.rms(out['final'])
    for i, name in enumerate(meas.names):
        sigma, how = problem.noise[name]
        if name in problem.raised:
            how += f'; weighted by its rms ({meas.sigma[name]:.4g}): the model explains it '\
                'only to that'
        lines.append(f'{name:<14} {meas.units[name]:<5} {sigma:>12.4g} {rms0[i]:>12.4g} '
                     f'{rms1[i]:>12.4g} {rms1[i] / sigma:>10.3g}  {how}')
    lines += ['', 'exact data: no covariance, no intervals' if getattr(problem, 'exact', False)
              else f'covariance: HAC sandwich (Bartlett, bandwidth {res.bandwidth} steps); '
              f'{pct} % intervals from the t distribution with {res.dof} degrees of freedom',
              f'{problem.evaluations} re-simulations ({res.nfev} in the fit), '
              f'{out["wall"]:.2f} s wall; optimiser: {res.message}']
    return option_text('\n'.join(lines), name_of)
