"""
The printed summary of a frequency response: resonances, bandwidth, margins, amplitude range.

- Resonances and anti-resonances: of a linear response, its lightly damped
  poles and zeros (complex pairs inside the band; frequency |s| / 2 pi [Hz],
  damping -Re s / |s|); of a measured one, the peaks and dips of |H| that
  stand out by more than PROMINENCE_DB from their neighbours, the damping by
  the half-power width (f2 - f1) / (2 f_n) where it lies inside the band.
- Bandwidth: of a closed loop (and T) the first frequency where |H| falls
  3 dB below its low-frequency value; of L its gain crossover (|L| = 1); of S
  where |S| first rises to -3 dB. Interpolated in log frequency.
- Margins of a loop quantity, from L: gain margin -20 log|L| at the phase
  crossovers (phase -180 deg mod 360), phase margin 180 deg + angle L at the
  gain crossover, peak sensitivity max |1 / (1 + L)|.
- Amplitude dependence: the frequencies and amplitudes at which the gain
  differs by more than 1 dB from that at the largest amplitude.

A figure the data cannot support is said in words, never printed as NaN or
inf: no bandwidth in the band (and why), no phase crossover (no gain
margin), no gain crossover (no phase margin), a damping whose half-power
points lie outside the band; a linear model whose thread is stuck at rest is
said once (:data:`STUCK`).
"""
import math

import numpy as np

__all__ = ['amplitude_range', 'bandwidth', 'bandwidth_text', 'margin_text', 'margins',
           'resonances', 'STUCK', 'summary_lines']

PROMINENCE_DB = 3.0    #: how far a measured peak or dip stands out [dB]
LIGHT = 0.7            #: damping below which a pole or zero pair counts as a (anti-)resonance


def _crossing(f, y, level):
    """Return the first f where y (sampled at f) crosses level, log-interpolated; NaN if none."""
    d = np.asarray(y, float) - level
    idx = np.nonzero(np.sign(d[:-1]) * np.sign(d[1:]) < 0)[0]
    if not len(idx):
        return math.nan
    i = idx[0]
    t = d[i] / (d[i] - d[i + 1])
    return float(math.exp(math.log(f[i]) + t * (math.log(f[i + 1]) - math.log(f[i]))))


def _pairs(s, fmin, fmax):
    s = np.asarray(s if s is not None else [], complex)
    s = s[(s.imag > 0.0) & np.isfinite(s)]
    out = []
    for x in s:
        fn = abs(x) / (2.0 * math.pi)
        zeta = -x.real / abs(x)
        if fmin <= fn <= fmax and zeta < LIGHT:
            out.append((float(fn), float(zeta)))
    return sorted(out)


def _peaks(f, db, sign):
    """Return [(f_n, zeta)] of the peaks (sign +1) or dips (-1) of a measured |H| [dB]."""
    y = sign * np.asarray(db, float)
    out = []
    for i in range(1, len(y) - 1):
        if not (y[i] > y[i - 1] and y[i] >= y[i + 1]):
            continue
        left, right = y[:i].min(), y[i + 1:].min()
        if y[i] - max(left, right) < PROMINENCE_DB:
            continue
        lo = _crossing(f[:i + 1][::-1], y[:i + 1][::-1], y[i] - 3.0)
        hi = _crossing(f[i:], y[i:], y[i] - 3.0)
        zeta = (hi - lo) / (2.0 * f[i]) if math.isfinite(lo) and math.isfinite(hi) else math.nan
        out.append((float(f[i]), float(zeta)))
    return out


def resonances(resp):
    """Return (resonances, anti-resonances): lists of (frequency [Hz], damping [-])."""
    f = resp.frequency
    if resp.poles is not None:
        return _pairs(resp.poles, f[0], f[-1]), _pairs(resp.zeros, f[0], f[-1])
    db = resp.magnitude_db
    ok = np.isfinite(db)
    return _peaks(f[ok], db[ok], 1.0), _peaks(f[ok], db[ok], -1.0)


def bandwidth(resp):
    """Return the bandwidth [Hz] of a response (see the module doc); NaN if not in the band."""
    f, db = _finite(resp)                    # points without a result (or a zero gain) left out
    if len(f) < 2:
        return math.nan
    if resp.output == 'L':
        return _crossing(f, db, 0.0)
    if resp.output == 'S':
        return _crossing(f, db, -3.0)
    return _crossing(f, db, db[0] - 3.0)


def margins(f, loop):
    """
    Return dict(gain_margin_db, gain_margin_frequency [Hz], phase_margin_deg, crossover [Hz], ms).

    Parameters
    ----------
    f : numpy.ndarray
        Frequencies [Hz].
    loop : numpy.ndarray of complex
        L at f.

    """
    loop = np.asarray(loop)
    ok = np.isfinite(loop) & (loop != 0.0)   # points without a result (or a phase) left out
    f, loop = np.asarray(f, float)[ok], loop[ok]
    if len(f) < 2:
        return dict(gain_margin_db=math.inf, gain_margin_frequency=math.nan,
                    phase_margin_deg=math.nan, crossover=math.nan, ms=math.nan)
    mag = np.abs(loop)
    ph = np.degrees(np.unwrap(np.angle(loop)))
    wc = _crossing(f, 20.0 * np.log10(mag), 0.0)
    pm = math.nan
    if math.isfinite(wc):
        lw = np.interp(math.log(wc), np.log(f), ph)
        pm = (lw + 180.0) % 360.0
        pm = pm - 360.0 if pm > 180.0 else pm
    gm, wg = math.inf, math.nan
    shifted = (ph + 180.0) / 360.0          # an integer at every phase crossover
    for k in np.unique(np.round(shifted)):
        w = _crossing(f, shifted, k)
        if math.isfinite(w):
            g = -20.0 * math.log10(np.interp(math.log(w), np.log(f), mag))
            if g < gm:
                gm, wg = g, w
    with np.errstate(divide='ignore'):      # 1 + L = 0: unbounded
        ms = float(np.max(1.0 / np.abs(1.0 + loop)))
    return dict(gain_margin_db=gm, gain_margin_frequency=wg, phase_margin_deg=pm,
                crossover=wc, ms=ms)


def amplitude_range(responses, limit_db=1.0):
    """
    Return (frequencies [Hz], amplitudes) where the gain is > limit_db off the largest amplitude's.

    Parameters
    ----------
    responses : list of FrequencyResponse
        One per amplitude, on the same frequencies.
    limit_db : float
        Threshold [dB].

    """
    if len(responses) < 2:
        return [], []
    ref = max(responses, key=lambda r: r.amplitude)
    freqs, amps = set(), set()
    for r in responses:
        if r is ref or len(r.frequency) != len(ref.frequency):
            continue
        d = np.abs(r.magnitude_db - ref.magnitude_db) > limit_db
        freqs.update(r.frequency[d].tolist())
        if d.any():
            amps.add(r.amplitude)
    return sorted(freqs), sorted(amps)


#: Said once when a linear model's thread is stuck at rest (the options marked ``<<name>>``:
#: the verb names them by their flags).
STUCK = ('the thread is stuck at rest (stiction): the motor turns only by straining the '
         'contact; use <<speed>> V for a sliding operating point or <<rest>> free')


def _band(r):
    f = r.frequency
    return f'{f[0]:.4g}-{f[-1]:.4g} Hz' if len(f) else 'the band'


def _finite(r):
    """Return (f, dB) at the frequencies where |H| is finite and nonzero."""
    db = r.magnitude_db
    ok = np.isfinite(db)
    return r.frequency[ok], db[ok]


def bandwidth_text(r):
    """Return the summary's bandwidth line: a frequency, or 'none' and why."""
    bw = bandwidth(r)
    if math.isfinite(bw):
        return f'bandwidth: {bw:.4g} Hz'
    f, db = _finite(r)
    if len(f) < 2:
        why = 'too few points with a finite gain'
    elif r.output == 'L':
        why = ('|L| stays below 0 dB: no crossover' if db.max() < 0.0
               else '|L| stays above 0 dB: no crossover')
    elif r.output == 'S':
        why = ('|S| stays above -3 dB: no disturbance rejection' if db.min() > -3.0
               else '|S| stays below -3 dB')
    else:
        why = 'the gain never falls 3 dB below its low-frequency value'
    return f'bandwidth: none in {_band(r)} ({why})'


def margin_text(r, loop):
    """Return the summary's margins line of L at r's frequencies: numbers, or 'none' and why."""
    m = margins(r.frequency, loop)
    if math.isnan(m['ms']):
        return 'margins: none (too few points with a finite, nonzero L)'
    parts = []
    if math.isfinite(m['gain_margin_db']):
        parts.append(f'gain margin {m["gain_margin_db"]:.3g} dB at '
                     f'{m["gain_margin_frequency"]:.4g} Hz')
    else:
        parts.append('gain margin: none (the phase never crosses -180 deg in the band)')
    if math.isfinite(m['phase_margin_deg']):
        parts.append(f'phase margin {m["phase_margin_deg"]:.3g} deg at {m["crossover"]:.4g} Hz')
    else:
        mag = np.abs(loop)
        mag = mag[np.isfinite(mag)]
        side = 'below' if len(mag) and mag.max() < 1.0 else 'above'
        parts.append(f'phase margin: none (|L| stays {side} 0 dB: no crossover in the band)')
    if math.isfinite(m['ms']):
        db = round(20.0 * math.log10(m['ms']), 2) + 0.0        # no '-0.00'
        parts.append(f'peak sensitivity {m["ms"]:.3g} ({db:.2f} dB)')
    else:
        parts.append('peak sensitivity: unbounded (1 + L = 0 in the band)')
    return ', '.join(parts)


def _items(items):
    """Return '(f Hz (damping z), ...' or 'none'; a damping the band cannot resolve said so."""
    return ', '.join(f'{fn:.4g} Hz (damping {z:.3g})' if math.isfinite(z)
                     else f'{fn:.4g} Hz (damping not resolved: its half-power points are '
                     'outside the band)' for fn, z in items) or 'none'


def summary_lines(responses, linear=None):
    """
    Return the summary as text lines for a list of responses (and the linear model's).

    An option the lines name is marked ``<<keyword>>`` (:data:`STUCK`): the
    verb names it by its flag (:func:`leadscrew_sim.offline.options.option_text`).
    """
    lines = []
    every = ([linear] if linear is not None else []) + list(responses)
    if any(r.state == 'stuck' for r in every):
        lines.append(STUCK)
    for r in every:
        tag = r.source + ('' if math.isnan(r.amplitude) else f' at amplitude {r.amplitude:.4g}')
        lines.append(f'{r.input} -> {r.output} ({tag}):')
        lines.extend(f'  note: {n}' for n in r.notes)
        res, anti = resonances(r)
        lines.append(f'  resonances: {_items(res)}')
        lines.append(f'  anti-resonances: {_items(anti)}')
        lines.append(f'  {bandwidth_text(r)}')
        if r.loop_gain is not None or r.output in ('L', 'S', 'T') and r.source != 'linear':
            lg = r.loop_gain if r.loop_gain is not None else _loop_from(r)
            lines.append(f'  {margin_text(r, lg)}')
        coh = r.coherence[np.isfinite(r.coherence)]
        if len(coh):
            lines.append(f'  coherence: min {coh.min():.3f}, median {np.median(coh):.3f}')
    freqs, amps = amplitude_range(list(responses))
    if freqs:
        lines.append(f'gain depends on amplitude by > 1 dB at {freqs[0]:.4g}..{freqs[-1]:.4g} Hz '
                     f'for amplitudes {amps[0]:.4g}..{amps[-1]:.4g} (against the largest)')
    elif len(responses) > 1 and _compared(responses):
        lines.append('gain within 1 dB across the amplitudes')
    return lines


def _compared(responses):
    """Return True if the amplitudes' gains share a finite point to compare."""
    ok = [np.isfinite(r.magnitude_db) for r in responses]
    return len({len(o) for o in ok}) == 1 and bool(np.logical_and.reduce(ok).any())


def _loop_from(r):
    """Return L from a measured S (1 / S - 1), T (T / (1 - T)) or L."""
    h = r.response
    with np.errstate(divide='ignore', invalid='ignore'):
        if r.output == 'S':
            return 1.0 / h - 1.0
        return h / (1.0 - h) if r.output == 'T' else h
