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
"""
import math

import numpy as np

__all__ = ['amplitude_range', 'bandwidth', 'margins', 'resonances', 'summary_lines']

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
    db = resp.magnitude_db
    if resp.output == 'L':
        return _crossing(resp.frequency, db, 0.0)
    if resp.output == 'S':
        return _crossing(resp.frequency, db, -3.0)
    return _crossing(resp.frequency, db, db[0] - 3.0)


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
    return dict(gain_margin_db=gm, gain_margin_frequency=wg, phase_margin_deg=pm,
                crossover=wc, ms=float(np.max(1.0 / np.abs(1.0 + loop))))


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


def summary_lines(responses, linear=None):
    """Return the summary as text lines for a list of responses (and the linear model's)."""
    lines = []
    for r in ([linear] if linear is not None else []) + list(responses):
        tag = r.source + ('' if math.isnan(r.amplitude) else f' at amplitude {r.amplitude:.4g}')
        lines.append(f'{r.input} -> {r.output} ({tag}):')
        lines.extend(f'  note: {n}' for n in r.notes)
        res, anti = resonances(r)
        for name, items in (('resonances', res), ('anti-resonances', anti)):
            text = ', '.join(f'{fn:.4g} Hz (damping {z:.3g})' for fn, z in items) or 'none'
            lines.append(f'  {name}: {text}')
        lines.append(f'  bandwidth: {bandwidth(r):.4g} Hz')
        if r.loop_gain is not None or r.output in ('L', 'S', 'T') and r.source != 'linear':
            lg = r.loop_gain if r.loop_gain is not None else _loop_from(r)
            m = margins(r.frequency, lg)
            lines.append(f'  gain margin {m["gain_margin_db"]:.3g} dB at '
                         f'{m["gain_margin_frequency"]:.4g} Hz, phase margin '
                         f'{m["phase_margin_deg"]:.3g} deg at {m["crossover"]:.4g} Hz, '
                         f'peak sensitivity {m["ms"]:.3g} ({20 * math.log10(m["ms"]):.2f} dB)')
        coh = r.coherence[np.isfinite(r.coherence)]
        if len(coh):
            lines.append(f'  coherence: min {coh.min():.3f}, median {np.median(coh):.3f}')
    freqs, amps = amplitude_range(list(responses))
    if freqs:
        lines.append(f'gain depends on amplitude by > 1 dB at {freqs[0]:.4g}..{freqs[-1]:.4g} Hz '
                     f'for amplitudes {amps[0]:.4g}..{amps[-1]:.4g} (against the largest)')
    elif len(responses) > 1:
        lines.append('gain within 1 dB across the amplitudes')
    return lines


def _loop_from(r):
    """Return L from a measured S (1 / S - 1), T (T / (1 - T)) or L."""
    h = r.response
    return {'L': h, 'S': 1.0 / h - 1.0, 'T': h / (1.0 - h)}[r.output]
