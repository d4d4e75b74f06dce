"""How each report section reads on the page: sentences, tables and figures (blocks for html)."""
from . import plots

#: (number, key, anchor id) of the page's sections in order.
ORDER = ((1, 'axis', 'axis'), (2, 'identify', 'parameters'), (3, 'twin', 'twin'),
         (4, 'friction', 'friction'), (5, 'backlash', 'backlash'),
         (6, 'frequency response', 'frequency-response'), (7, 'stability', 'stability'),
         (8, 'iso230', 'iso230'), (9, 'stepper', 'stepper'),
         (10, 'undetermined', 'undetermined'))


def _um(x):
    return None if x is None else x * 1e6


def axis(ctx, s):
    """Section 1: preset, sensors, duration, segments found and missing."""
    b = [('p', f'Preset {s["preset"]} ({s["drive_type"]} drive), {s["duration_s"]:.2f} s '
               f'recorded; the segments come from {s["segments_source"]}.'),
         ('table', ['sensor setting', 'value'], [[k, v] for k, v in s['sensors'].items()]),
         ('p', f'The sensor settings: {s.get("sensors_from", "")}.'),
         ('table', ['segment', 'start [s]', 'end [s]'],
          [[n, a, e] for n, (a, e) in s['segments'].items()])]
    if s.get('mapping'):
        mp = s['mapping']
        b.insert(1, ('table', ['mapping of the real axis\'s recording', 'value'], [
            ['states (sensor_msgs/JointState)', mp['state_topic']],
            [f'commands ({mp["command_type"]})', mp['command_topic']],
            ['screw joint, nut joint', ', '.join(mp['joints'])],
            ['re-simulation step rate [Hz]', mp['step_rate_hz']],
            ['command-to-state delay [s]', mp['command_delay_s']]]))
    if s['missing']:
        b.append(('table', ['missing segment', 'what it would add'],
                  [[m['part'], m['would_add']] for m in s['missing']]))
    return b


def parameters(ctx, s):
    """Section 2: value, 95 % interval, verdict, correlations."""
    b = []
    if s.get('window'):
        b.append(('p', f'Fitted {", ".join(s["fitted"])} on the recording from '
                       f'{s["window"][0]:.2f} to {s["window"][1]:.2f} s (the sweep); '
                       f'{s["not_fitted"]}.'))
    rows = [[r['name'], r['start'], r['value'], r['lower'], r['upper'], r['verdict']]
            for r in s['parameters']]
    if rows:
        b.append(('table', ['parameter', 'start', 'value', '95 % lower', '95 % upper',
                            'verdict'], rows))
        names = [r['name'] for r in s['parameters']]
        b.append(('table', ['correlation'] + names,
                  [[n] + row for n, row in zip(names, s['correlation'])]))
    if s.get('rms_over_noise'):
        b.append(('table', ['signal', 'residual RMS / noise [-]'],
                  [[k, v] for k, v in s['rms_over_noise'].items()]))
    return b


def twin(ctx, s):
    """Section 3: the held-out parts, measured against twin."""
    b = []
    if s.get('sentence'):
        noise = ('no noise level of the nut position known' if s['noise_um'] is None else
                 f'noise {s["noise_um"]:.3g} um RMS')
        b.append(('sentence', s['sentence'] + '.'))
        b.append(('p', f'The nut position\'s reading: {noise}.' + (
            ' ' + s['floor'][0].upper() + s['floor'][1:] + '.' if s.get('floor') else '')))
        rows = [[part, d['rms_um'], d['max_um'], d.get('rms_over_noise'),
                 d.get('max_over_noise')] for part, d in s['parts'].items()]
        h = s['held_out']
        rows.append(['all held-out', h['rms_um'], h['max_um'], h.get('rms_over_noise'),
                     h.get('max_over_noise')])
        b.append(('table', ['part (not fitted)', 'RMS [um]', 'max [um]', 'RMS / noise [-]',
                            'max / noise [-]'], rows))
        if s.get('drifting'):
            b.append(('table', ['drifting part (not fitted)', 'RMS [um]', 'max [um]'],
                      [[p, d['rms_um'], d['max_um']] for p, d in s['drifting'].items()]))
        b.append(('p', 'The fit saw the ' + '; '.join(ctx.fitted_on) + '. The twin reads '
                       + s['sensors'].split('the twin reads ', 1)[-1] + '.'))
        b.append(('img', plots.twin(ctx, {p: d['window'] for p, d in s['parts'].items()}),
                  'measured and twin nut position on the held-out parts'))
    return b


def friction(ctx, s):
    """Section 4: Stribeck points, breakaway, efficiencies, self-locking."""
    b = [('table', ['figure', 'value'], [
        ['static band of the twin, +theta [N m]', s['static_band_twin']['up']],
        ['static band of the twin, -theta [N m]', s['static_band_twin']['down']],
        ['self-locking at rest', 'yes' if s['self_locking'] else 'no'],
        ['self-locking in motion', 'yes' if s['self_locking_in_motion'] else 'no']])]
    if 'breakaway' in s:
        b.append(('table', ['breakaway (measured)', 'torque [N m]'],
                  [[f'toward {k}theta', v] for k, v in s['breakaway'].items()]))
    if s.get('stribeck'):
        eff, tw = s.get('efficiency_measured', {}), s.get('efficiency_twin', {})
        th = s.get('efficiency_thread', {})
        b.append(('table', ['efficiency at the fastest level', 'measured', 'twin',
                            'thread alone (closed form)'],
                  [['forward', eff.get('forward'), tw.get('forward'), th.get('forward')],
                   ['back-driving', eff.get('backdrive'), tw.get('backdrive'),
                    th.get('backdrive')]]))
        b.append(('p', 'Measured and twin: load power over motor power on the level (bearing '
                       'and guide losses included); the closed form is the thread\'s alone.'))
        b.append(('img', plots.stribeck(s), 'Stribeck points'))
    return b


def backlash(ctx, s):
    """Sections 5 and 8: reversal figures, measured and twin."""
    b = []
    rows = []
    for key in ('measured', 'twin'):
        r = s.get(key)
        if r:
            rows.append([key, _um(r['mean_reversal']), _um(r['max_reversal'])])
    if rows:
        b.append(('table', ['', 'mean reversal B [um]', 'max |B_i| [um]'], rows))
        b.append(('p', f'Backlash of the calibrated set: {s["backlash_calibrated"] * 1e6:.4g} um '
                       '(not fitted).' if 'backlash_calibrated' in s else ''))
        b.append(('img', plots.reversal(s), 'reversal deviations'))
    return b


def response(ctx, s):
    """Section 6: H1 and coherence over the linear model, resonances, bandwidth, margins."""
    b = [('p', f'Band up to the drive\'s Nyquist frequency {s["drive_nyquist_hz"]:.4g} Hz.')]
    if s.get('measured') and s['measured'].get('coherent_band_hz'):
        lo, hi = s['measured']['coherent_band_hz']
        b.append(('p', f'Coherence at least 0.9 between {lo:.3g} and {hi:.3g} Hz.'))
    if 'bandwidth_hz' in s:
        b.append(('p', 'Velocity command to motor velocity: bandwidth ' + (
            f'{s["bandwidth_hz"]:.4g} Hz' if s['bandwidth_hz'] else 'not in the band') + '; '
            'resonances ' + (', '.join(f'{r["frequency"]:.4g} Hz (zeta {r["damping"]:.3g})'
                                       for r in s['resonances']) or 'none in the band') + '.'))
    if s.get('loops'):
        rows = [[loop, m.get('gain_margin_db'), m.get('gain_margin_frequency'),
                 m.get('phase_margin_deg'), m.get('crossover'), m.get('ms')]
                for loop, m in s['loops'].items()]
        b.append(('table', ['loop', 'gain margin [dB]', 'at [Hz]', 'phase margin [deg]',
                            'crossover [Hz]', 'peak sensitivity Ms [-]'], rows))
    if s.get('linear') or s.get('measured'):
        b.append(('img', plots.bode(s), 'Bode plot'))
    return b


def stability(ctx, s):
    """Section 7: the map and the margin."""
    b = [('p', f'Growth rate of steady sliding (linear, velocity loop) over nut speeds up to the '
               f'velocity limit ({s["velocity_limit_speed"] * 1e3:.4g} mm/s) and {s["spread"]}.')]
    if s.get('stick_slip'):
        b.append(('sentence', s['stick_slip'] + '.'))
    b.append(('img', plots.stability(s), 'stability map'))
    return b


def stepper(ctx, s):
    """Section 9: pull-out curve and load line."""
    b = [('sentence', s['verdict'] + '.')]
    if s.get('knee'):
        b.append(('p', f'The pull-out torque falls below 90 % of its largest from '
                       f'{s["knee"]:.0f} full steps/s (the knee).'))
    if s.get('lost_steps'):
        b.append(('p', s['lost_steps'] + '.'))
    b.append(('img', plots.pullout(s), 'pull-out curve'))
    return b


def undetermined(ctx, s):
    """Section 10: everything the sections could not determine."""
    return [('cannot', s['lines'])] if s['lines'] else [('p', 'Nothing.')]


_VIEWS = {'axis': axis, 'identify': parameters, 'twin': twin, 'friction': friction,
          'backlash': backlash, 'frequency response': response, 'stability': stability,
          'iso230': backlash, 'stepper': stepper, 'undetermined': undetermined}


def sections(ctx, report):
    """
    Return [(number, id, heading, blocks)] of the page from the report's sections.

    An option a text names is marked ``<<keyword>>`` (:func:`..options.option_text`).
    """
    out = []
    for number, key, sid in ORDER:
        s = report.get(key)
        if s is None:
            heading = 'Stepper' if key == 'stepper' else key
            out.append((number, sid, heading, [('p', 'Not a stepper axis: no pull-out curve.')]))
            continue
        blocks = _VIEWS[key](ctx, s)
        if key == 'iso230' and 'measured' not in s:
            blocks = [('p', 'No iso230 segment (run excite commission <<opt>> iso230=1).')]
        if key != 'undetermined':
            blocks.append(('cannot', s.get('cannot', [])))
        out.append((number, sid, s.get('title', key), blocks))
    return out
