"""
The inputs of ``identify``: starting values, fitted names, measured signals, foreign recordings.

A recording of another source (:class:`ForeignReplay`, of
:mod:`leadscrew_sim.offline.foreign.replay`) is a JointState state topic and
a command topic, mapped by the options; its steps and commands go through the
node's command rules as a leadscrew_sim recording's do.
"""
import numpy as np

from ..foreign.replay import ForeignReplay  # noqa: F401 - imported from here
from ..options import load_params, parse_sets, RunError
from ...analysis.identify import fit as ident
from ...core.params import ScrewParams
from ...core.presets import load_preset, preset_names
from ...io import cdr as C
from ...io.run_file import PARAMS_RECORD


#: Smallest noise level used as a weight [unit]: the data's own estimate may be 0.
SIGMA_FLOOR = {'screw_angle': 1e-9, 'nut_position': 1e-12, 'motor_torque': 1e-9}

#: The numerical floor of a signal's noise level relative to its recorded range: the
#: noise-free re-simulation reproduces a signal to far better (re-simulations of the still
#: tr12x3 with every fittable parameter moved by 1e-9 relative differ by 1.5e-17 rad RMS),
#: so a change below it is no information.
RELATIVE_FLOOR = 1e-9

#: How a noise level is known when it is the numerical floor (exact data).
FLOOR = 'numerical floor'


def fit_names(text):
    """Return the parameter names of the ``fit`` option (default :data:`DEFAULT_FIT`), checked."""
    if text is None:
        return list(ident.DEFAULT_FIT)
    names = [n.strip() for n in text.split(',') if n.strip()]
    for n in names:
        if n not in ident.FITTABLE:
            raise RunError(f"<<fit>>: '{n}' is not a fittable parameter (fittable: "
                           f"{', '.join(ident.FITTABLE)})")
    if not names or len(set(names)) != len(names):
        raise RunError(f'<<fit>> {text!r}: give distinct parameter names, comma separated')
    return names


def start_params(args, rec):
    """Return (starting ScrewParams, its label): preset, params and set, else the named preset."""
    phys, run_ov = parse_sets(args.set)
    if run_ov:
        raise RunError('identify <<set>> accepts physics parameters only')
    if args.preset or args.params:
        params, label, _extra = load_params(args, phys)
        return params, label
    meta = rec.record(PARAMS_RECORD) or {}
    label = meta.get('preset') if meta.get('preset') in preset_names() else 'tr12x3'
    params = load_preset(label)
    return (ScrewParams.from_dict(phys, base=params) if phys else params), label


def check_geometry(start, recorded):
    """Refuse a starting set whose read-only geometry differs from the recording's."""
    info = ScrewParams.field_info()
    for name, (_t, _d, md) in info.items():
        if md.get('read_only') and name not in ('linear_scale', 'initial_position') and \
                getattr(start, name) != getattr(recorded, name):
            raise RunError(f'the starting set has {name}={getattr(start, name)!r}, the '
                           f'recording {getattr(recorded, name)!r}: choose the preset or '
                           'parameter file of this axis (<<preset>>, <<params>>)')


def measurements(path, data, recorded, torque_only, foreign, times=None):
    """
    Return (Measurements, {signal: (noise level, how it is known)}) of a recording.

    A noise level comes from the sensor where the sensor is known: a
    leadscrew_sim recording's sensor parameters (an ideal sensor there reads
    exactly: its level is the floor); it is then hypot(noise, q / sqrt(12))
    with the quantisation step q. A foreign recording's noise is not known,
    whatever the starting set (``preset``, ``params``, ``set``) says
    (a set whose level is off by more than 2 times is told): it is the
    data's estimate (:func:`data_level`): the white
    noise of the second differences, and at least q / sqrt(12) of the step
    the readings move in (:func:`reading_quantum`), so that a quantised
    signal whose noise is below its step (most second differences exactly
    0) is not taken for an exact one. Never below the numerical floor:
    :data:`SIGMA_FLOOR` or :data:`RELATIVE_FLOOR` of the signal's range,
    whichever is larger (then told as :data:`FLOOR`). ``times``: per step the
    time of its sample [steps] (NaN: none), for samples off the step grid
    (a foreign recording's stamps); None: on the grid.
    """
    levels = sensor_levels(recorded)
    declared = {}
    if not foreign:         # an ideal sensor of our own recording is known: it reads exactly
        levels = {'screw_angle': 0.0, 'nut_position': 0.0, **levels}
    else:                   # a real axis's noise is what its data show, not what a set says
        declared, levels = levels, {}
    source = 'sensor parameters'
    signals, sigma, noise = {}, {}, {}
    wanted = ['screw_angle'] + (['nut_position'] if recorded.linear_scale else []) + \
        ([] if torque_only else ['motor_torque'])
    for name in wanted:
        y = data[name]
        if not np.isfinite(y).any():
            continue
        if name in levels:
            s, how = levels[name], source
        else:
            s, how = data_level(y, times)
            said = declared.get(name)
            if said is not None and not 0.5 <= said / max(s, 1e-300) <= 2.0:
                how += f' (the starting set\'s sensor parameters say {said:.3g})'
        floor = max(SIGMA_FLOOR[name], RELATIVE_FLOOR * float(np.ptp(y[np.isfinite(y)])))
        if s <= floor:
            s, how = floor, FLOOR
        signals[name], sigma[name], noise[name] = y, s, (s, how)
    if not signals:
        raise RunError(f'{path}: no measured joint states to fit against')
    return ident.Measurements(signals, sigma), noise


def data_sensors(params, data, noise):
    """
    Return the sensor parameters the data show where the sensors are not known.

    The encoder's counts from the step its readings move in (2 pi / q, when
    that is near a whole number) and its noise from the estimated level less
    the quantisation; the scale's resolution and noise alike. A quantiser
    ``params`` declares is kept; the noise is always the data's. Used to
    re-simulate the recorded sensor chain (the drive loop's response to its
    sensors) of a foreign recording.
    """
    out = {n: getattr(params, n) for n in ('encoder_counts', 'encoder_noise', 'linear_scale',
                                           'scale_resolution', 'scale_noise')}
    quanta = quantisation(params)
    for name in ('screw_angle', 'nut_position'):
        if name not in noise or noise[name][1] == FLOOR:
            continue
        # a declared quantiser is a fact of the sensor; its noise is what the data show
        q = quanta.get(name, 0.0) * np.sqrt(12.0) or reading_quantum(data[name])
        white = float(np.sqrt(max(noise[name][0] ** 2 - q ** 2 / 12.0, 0.0)))
        if name == 'screw_angle':
            counts = 2.0 * np.pi / q if q > 0.0 else 0.0
            out['encoder_counts'] = int(round(counts)) if counts >= 2.0 and \
                abs(counts - round(counts)) < 1e-3 * counts else 0
            out['encoder_noise'] = white if out['encoder_counts'] else noise[name][0]
        else:
            out['scale_resolution'], out['scale_noise'] = q, white
    return out


#: How a noise level is known when it is estimated from the data.
ESTIMATED = 'estimated from the data'


def sensor_levels(params):
    """
    Return {signal: noise level [unit]} of the known (non-ideal) sensors of ``params``.

    hypot(Gaussian noise, :func:`quantisation`): an ideal sensor (no counts,
    noise or resolution) is unknown and left out, and so is the nut signal
    without a linear scale (it is the encoder's through the lead).
    """
    quanta = quantisation(params)
    noise = {'screw_angle': params.encoder_noise,
             'nut_position': params.scale_noise if params.linear_scale else 0.0}
    out = {}
    for name, n in noise.items():
        level = float(np.hypot(n, quanta.get(name, 0.0)))
        if level > 0.0:
            out[name] = level
    return out


def data_level(y, t=None):
    """
    Return (noise level [unit], how it is known) of a signal whose sensor is not known.

    The white noise of its second differences (:func:`..analysis.identify.noise.noise_estimate`),
    and at least q / sqrt(12) when the readings move in whole steps of q
    (:func:`reading_quantum`): a quantiser whose noise is below its step
    reads the same value for many steps, the median of the second differences
    is then 0, while each reading is still up to q / 2 off. ``t``: the
    samples' times where they are not equally spaced (None: they are).
    """
    s, how = ident.noise_estimate(y, t), ESTIMATED
    q = reading_quantum(y)
    if q > 0.0 and q / np.sqrt(12.0) > s:
        s, how = q / np.sqrt(12.0), f'{ESTIMATED} (readings in steps of {q:.4g}: q / sqrt(12))'
    return s, how


#: Least number of nonzero increments, and the share of the readings that must lie on the
#: grid of the smallest (to a tolerance of QUANTUM_TOL of it), that make readings step-wise.
QUANTUM_COUNT, QUANTUM_SHARE, QUANTUM_TOL = 20, 0.95, 0.02


def reading_quantum(y):
    """
    Return the step q [unit] a signal's readings move in (0: not step-wise).

    Read from the histogram of the increments: the smallest nonzero increment
    (the median of those within 1.5 times the least, against round-off) is
    k steps of q, the smallest k = 1, 2, .. for which the readings are step-wise when at least
    :data:`QUANTUM_SHARE` of them lie on one grid of that step (to
    :data:`QUANTUM_TOL` of it, about a common offset: a sensor's bias or
    homing). A smooth signal is not: even where it moves at constant speeds
    whose increments are multiples of one another, each speed change puts
    its readings on another grid.
    """
    y = np.asarray(y, dtype=float)
    y = y[np.isfinite(y)]
    if len(y) < 3:
        return 0.0
    d = np.abs(np.diff(y))
    span = float(np.ptp(y))
    nz = d[d > 1e-9 * span] if span > 0 else d[:0]
    if len(nz) < QUANTUM_COUNT:
        return 0.0
    least = float(np.median(nz[nz <= 1.5 * nz.min()]))
    for k in range(1, QUANTUM_DIVISORS + 1):     # the least increment may be k steps
        q = least / k
        phase = np.mod((y - y[0]) / q, 1.0)
        centre = np.angle(np.mean(np.exp(2j * np.pi * phase))) / (2.0 * np.pi)
        off = np.mod(phase - centre + 0.5, 1.0) - 0.5
        if np.mean(np.abs(off) <= QUANTUM_TOL) >= QUANTUM_SHARE and _jitters(y, q):
            return q
    return 0.0


def _jitters(y, q):
    """
    Return whether readings ``y`` jitter by whole steps ``q`` (a quantiser, not a smooth motion).

    A quantiser's second differences are 0 or whole nonzero multiples of q
    (a reading one step early or late), and there are many of them; a
    smooth signal's are far below q, and one at constant speed has none.
    """
    d2 = np.diff(y, 2)
    big = d2[np.abs(d2) > 0.5 * q]
    if len(big) < QUANTUM_COUNT or len(big) < 0.5 * np.count_nonzero(np.abs(d2) > 1e-3 * q):
        return False
    r = big / q
    return bool(np.mean(np.abs(r - np.round(r)) <= QUANTUM_TOL) >= QUANTUM_SHARE)


#: Most steps the least increment of a moving quantised signal may span (the largest step
#: whose grid holds the readings is taken).
QUANTUM_DIVISORS = 16


def quantisation(params):
    """Return the quantisation noise q / sqrt(12) [unit] of each quantising position sensor."""
    out = {}
    if params.encoder_counts:
        out['screw_angle'] = 2.0 * np.pi / params.encoder_counts / np.sqrt(12.0)
    if params.linear_scale and params.scale_resolution:
        out['nut_position'] = params.scale_resolution / np.sqrt(12.0)
    return out


def _decode_states(states, t0, dt_ns, n, screw, nut):
    """Return {signal: array (n,)} of JointState messages [(log time, bytes)] by their stamps."""
    out = {s: np.full(n, np.nan) for s in ('screw_angle', 'nut_position', 'motor_torque')}
    for _t, data in states:
        stamp, names, pos, _vel, eff = C.decode_joint_state(data)
        k = (stamp - t0) // dt_ns - 1
        if not 0 <= k < n or (stamp - t0) % dt_ns:
            continue
        for j, name in enumerate(names):
            if name == screw:
                if j < len(pos):
                    out['screw_angle'][k] = pos[j]
                if j < len(eff):
                    out['motor_torque'][k] = eff[j]
            elif name == nut and j < len(pos):
                out['nut_position'][k] = pos[j]
    return out


def measured_of_resim(sim):
    """Return the recorded sensor signals of a leadscrew_sim recording (``Resim``) per step."""
    topic = sim.topics.get('joint_states')
    states = [(t, d) for t, tp, d in sim.rec.messages if tp == topic] if topic else []
    return _decode_states(states, sim.t0, sim.dt_ns, sim.n_steps,
                          sim.prefix + 'screw_joint', sim.prefix + 'nut_joint')
