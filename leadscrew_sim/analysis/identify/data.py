"""
The data of an identification: the measured signals going in, the verdicts coming out.

Measured signals (:class:`Measurements`): what the axis's sensors report on
the step grid, with the noise level that weights each and a free offset for
each position signal (the homing's zero).

A fitted parameter in the optimiser's coordinates (:class:`Coordinate`); the
Jacobian of the intervals (:func:`interval_jacobian`), the covariance of a fit
(:func:`sandwich`) and the verdicts (:func:`judge`): identified, or not
identifiable from the data and why.

A parameter is identified when its 95 % interval is narrower than
+-:data:`REL_MAX` of its size (its value, or its typical size when the value
is near 0). Otherwise the reason is told apart from the Jacobian J (of the
weighted residuals, in the optimiser's coordinates):

- no sensitivity: the column of J is zero, or so small that even with every
  other parameter known the interval would exceed the bar (the marginal
  standard error, the full one divided by the square root of its variance
  inflation factor VIF = (J^T J)^-1_ii (J^T J)_ii); for example the backlash
  of a run that never reverses, the stiction of a run that never breaks away;
- collinear: the marginal interval passes the bar but the full one does not:
  the parameter trades off against others (named: the largest correlation),
  and the data fix only a combination.

A parameter is identified only if moving it across its interval changes the
signals by more than their noise (|J column| x half-width > 1); exact data
(weights at the numerical floor) have no interval (:func:`_exact`). A
parameter the motion cannot show (:mod:`.degeneracy`: no reversal, no
breakaway, a single sliding speed) is not identifiable, whatever its column.
"""
import dataclasses
import math

import numpy as np

from . import linalg as la
from .covariance import sandwich, scaled_inverse

__all__ = ['Coordinate', 'interval_jacobian', 'judge', 'Measurements',
           'noiseless_sensors', 'sandwich', 'scaled_inverse', 'sensor_sigma', 'Verdict']

#: Largest relative half-width of a 95 % interval of an identified parameter.
REL_MAX = 0.5


@dataclasses.dataclass(frozen=True)
class Coordinate:
    """
    One fitted parameter in the optimiser's coordinates.

    z = v / scale (linear) or z = ln(v / scale) (log); bounds [lower, upper] in
    the parameter's unit.
    """

    name: str
    initial: float
    lower: float
    upper: float
    log: bool
    scale: float
    typical: float

    def to_z(self, v):
        """Return the coordinate of value ``v``."""
        return math.log(v / self.scale) if self.log else v / self.scale

    def to_value(self, z):
        """Return the value of coordinate ``z`` (clipped into the bounds)."""
        v = self.scale * math.exp(z) if self.log else z * self.scale
        return min(self.upper, max(self.lower, v))


def interval_jacobian(fun, z, r0, steps, lo=None, hi=None):
    """
    Return the difference Jacobian of ``fun`` at ``z``: per column the flattest of four.

    A re-simulation is piecewise smooth in its parameters: a breakaway, a
    flank change or a stick happens in a whole step, so a parameter change
    that moves it by one step makes the signals jump; and a parameter the
    signals hardly depend on changes them only by the solver's round-off.
    The smooth part is the derivative; a difference across a jump overstates
    it, and so does round-off divided by a small step (both understate the
    interval). Of the forward and backward differences of a small and a
    larger step, the one with the smallest norm crossed neither. A
    difference whose step leaves the bounds ``lo``, ``hi`` is not taken: the
    coordinate is clipped there, so it would be zero, the flattest, and a
    parameter fitted at its bound would seem to have no effect.
    """
    jac = np.empty((r0.size, len(z)))
    for i in range(len(z)):
        cols, inside = [], []
        for step in steps:
            h = step * max(1.0, abs(z[i]))
            for sign in (1.0, -1.0):
                zi = np.array(z, dtype=float)
                zi[i] += sign * h
                cols.append((fun(zi) - r0) / (sign * h))
                inside.append((lo is None or zi[i] >= lo[i]) and (hi is None or zi[i] <= hi[i]))
        kept = [c for c, ok in zip(cols, inside) if ok] or cols
        jac[:, i] = min(kept, key=la.norm)
    return jac


@dataclasses.dataclass(frozen=True)
class Verdict:
    """
    The verdict on one parameter, with its interval.

    ``lower``, ``upper``: the 95 % interval [unit of the parameter] (NaN when
    the parameter was not fitted); ``std``: its standard error; ``rel``: the
    interval's half-width relative to the parameter's size; ``exact``: seen by
    exact data, which give no statistical interval (fitted, not identified).
    """

    name: str
    identified: bool
    reason: str
    lower: float = math.nan
    upper: float = math.nan
    std: float = math.nan
    rel: float = math.nan
    exact: bool = False

    @property
    def status(self):
        """Return 'identified', 'exact data' or 'not identifiable'."""
        return 'identified' if self.identified else 'exact data' if self.exact else \
            'not identifiable'

    @property
    def fitted(self):
        """Return whether the fit keeps the parameter free (identified or exact data)."""
        return self.identified or self.exact


def t_quantile(level, dof):
    """Return the two-sided quantile of the t distribution of ``dof`` degrees of freedom."""
    from scipy.stats import t
    return float(t.ppf(0.5 + level / 2.0, dof))


def judge(coords, z, jac, cov, r, lo, hi, level, dof, hints=None, exact=False):
    """
    Return the :class:`Verdict` of each fitted coordinate.

    Parameters
    ----------
    coords : list of Coordinate
        The fitted parameters.
    z : numpy.ndarray
        Their coordinates at the solution.
    jac : numpy.ndarray
        Jacobian of the flattened weighted residuals with respect to z.
    cov : numpy.ndarray
        Covariance of z.
    r : numpy.ndarray
        The residuals at the solution (unused but for their count).
    lo, hi : numpy.ndarray or None
        Bounds of z (to say that a value sits on one).
    level : float
        Confidence level of the intervals.
    dof : int
        Degrees of freedom of the t quantile.
    hints : dict, optional
        name -> why the motion cannot determine it (:mod:`.degeneracy`): judged not
        identifiable for that reason.
    exact : bool
        Exact data (ideal sensors): no statistical interval (:func:`_exact`).

    """
    hints = hints or {}
    if exact:
        return [_degenerate(c.name, hints) or _exact(c, z[i], jac[:, i])
                for i, c in enumerate(coords)]
    tq = t_quantile(level, dof)
    jtj = la.gram(jac)
    inv = scaled_inverse(jtj)
    sd = np.sqrt(np.maximum(np.diag(cov), 0.0))
    d = np.where((sd > 0) & np.isfinite(sd), sd, 1.0)
    corr = np.where(np.isfinite(cov), cov, 0.0) / np.outer(d, d)
    out = []
    for i, c in enumerate(coords):
        v = c.to_value(z[i])
        za, zb = z[i] - tq * sd[i], z[i] + tq * sd[i]
        lower, upper = _interval(c, za, zb)
        size = max(abs(v), c.typical) if not c.log else v
        rel = 0.5 * (upper - lower) / size if size > 0 else math.inf
        std = _std_value(c, z[i], sd[i])
        col = float(np.sqrt(jtj[i, i]))
        vif = float(inv[i, i] * jtj[i, i]) if col > 0 else math.inf
        marginal = rel / math.sqrt(vif) if vif > 0 and math.isfinite(vif) else math.inf
        if c.name in hints:
            out.append(_degenerate(c.name, hints))
            continue
        if col == 0.0 or not math.isfinite(rel) and not math.isfinite(marginal):
            out.append(Verdict(c.name, False, 'no sensitivity: the re-simulated signals do '
                               'not change with it', math.nan, math.nan, math.nan,
                               math.inf))
            continue
        moved = col * (zb - za) / 2.0     # the signals' change across the interval [noise]
        if rel <= REL_MAX and not moved > 1.0:
            out.append(_unseen(c.name, rel, moved, lower, upper, std))
            continue
        if rel <= REL_MAX:
            where = ''
            if lo is not None and z[i] <= lo[i] + 1e-9 * max(1.0, abs(lo[i])):
                where = f' (at its lower bound {c.lower!r})'
            elif hi is not None and z[i] >= hi[i] - 1e-9 * max(1.0, abs(hi[i])):
                where = f' (at its upper bound {c.upper!r})'
            out.append(Verdict(c.name, True, f'identified: 95 % interval +-{100 * rel:.3g} %'
                               f'{where}', lower, upper, std, rel))
            continue
        if marginal > REL_MAX:
            reason = (f'too little sensitivity: even with every other parameter known the '
                      f'data fix it only to +-{100 * marginal:.3g} %')
        else:
            others = [(abs(corr[i, j]), j) for j in range(len(coords)) if j != i]
            _c, j = max(others) if others else (0.0, i)
            reason = (f'collinear with {coords[j].name} (correlation {corr[i, j]:+.3f}): the '
                      f'data fix only a combination; alone +-{100 * marginal:.3g} %, '
                      f'together +-{100 * rel:.3g} %')
        out.append(Verdict(c.name, False, reason, lower, upper, std, rel))
    return out


def _unseen(name, rel, moved, lower, upper, std):
    """Return the Verdict of an interval across which the signals move less than the noise."""
    return Verdict(name, False, f'too little sensitivity: moving it across its interval (+-'
                   f'{100 * rel:.3g} %) changes the re-simulated signals by {moved:.3g} of their '
                   f'noise, less than 1', lower, upper, std, rel)


def _degenerate(name, hints):
    """Return the Verdict of a parameter the motion cannot show (None when it can)."""
    if name not in hints:
        return None
    return Verdict(name, False, f'not identifiable: {hints[name]}', rel=math.inf)


def _exact(c, z, col):
    """Return the Verdict on exact data: seen if +-REL_MAX moves the signals above the floor."""
    size = max(abs(c.to_value(z)), c.typical)
    dz = math.log1p(REL_MAX) if c.log else REL_MAX * size / c.scale
    moved = la.norm(col) * dz
    if moved > 1.0:
        return Verdict(c.name, False, 'exact data: no statistical interval; moving it by '
                       f'+-{100 * REL_MAX:g} % changes the re-simulated signals by '
                       f'{moved:.3g} times the numerical floor', exact=True)
    return Verdict(c.name, False, 'no sensitivity: moving it by '
                   f'+-{100 * REL_MAX:g} % changes the exact re-simulated signals by '
                   f'{moved:.3g} of the numerical floor, less than 1', rel=math.inf)


def _interval(c, za, zb):
    """Return the interval [unit] of coordinates [za, zb], clipped into the bounds."""
    if c.log:
        a = c.scale * math.exp(min(za, 700.0))
        b = c.scale * math.exp(min(zb, 700.0))
    else:
        a, b = za * c.scale, zb * c.scale
    return max(c.lower, a), min(c.upper, b)


def _std_value(c, z, sd):
    """Return the standard error [unit] of a value from that of its coordinate."""
    return c.scale * math.exp(min(z, 700.0)) * sd if c.log else c.scale * sd


# Measured signals ----------------------------------------------------------------------

#: The signals an axis measures: (name, the ``model.run`` column it compares with, unit).
SIGNALS = (('screw_angle', 'sensor_screw_angle', 'rad'),
           ('nut_position', 'sensor_nut_position', 'm'),
           ('motor_torque', 'motor_torque', 'N m'))

#: Sensor parameters of an ideal re-simulation: no counts, noise or bias.
IDEAL_SENSORS = dict(encoder_counts=0, encoder_noise=0.0, encoder_bias=0.0,
                     scale_resolution=0.0, scale_noise=0.0, scale_bias=0.0)

#: A bias that changes no reading (|x| + 1e-300 == |x| for every reading but an exact 0).
NULL_BIAS = 1e-300


def noiseless_sensors(params):
    """
    Return the sensor parameters that re-simulate a recording's sensors without their noise.

    A sensor the recording had as ideal stays ideal (it reads the true position
    and rate). Any other keeps its bias but loses its counts (resolution) and
    noise; its bias is at least :data:`NULL_BIAS`, which keeps it a real sensor
    in the kernel: its velocity is the difference quotient of its readings
    over the drive period, as in the recording, so a drive loop closed over
    it has the recorded dynamics (an ideal sensor's true rate has none of the
    quotient's half-period delay).

    Parameters
    ----------
    params : ScrewParams
        The recording's sensor parameters.

    """
    out = dict(IDEAL_SENSORS)
    if params.encoder_counts or params.encoder_noise or params.encoder_bias:
        out['encoder_bias'] = params.encoder_bias or NULL_BIAS
    if params.scale_resolution or params.scale_noise or params.scale_bias:
        out['scale_bias'] = params.scale_bias or NULL_BIAS
    return out


#: Least residual rms / noise level of a signal that :meth:`Measurements.reweight` raises.
REWEIGHT = 2.0

#: Signals with a free offset: the zero of an encoder and of a scale is the homing's.
OFFSET_SIGNALS = ('screw_angle', 'nut_position')


def sensor_sigma(params):
    """
    Return the known noise level [unit] of each position signal of a recording's sensors.

    sigma^2 = noise^2 + q^2 / 12 (Gaussian noise, then quantisation to steps of q:
    2 pi / counts for the encoder, the resolution for the scale); None where
    the sensor is ideal (nothing known). Without a linear scale the nut signal
    is the encoder's through the lead, so it is left out (None).

    Parameters
    ----------
    params : ScrewParams
        The recording's sensor parameters.

    """
    q = 2.0 * math.pi / params.encoder_counts if params.encoder_counts else 0.0
    enc = math.hypot(params.encoder_noise, q / math.sqrt(12.0)) or None
    scale = math.hypot(params.scale_noise, params.scale_resolution / math.sqrt(12.0)) or None
    return {'screw_angle': enc, 'nut_position': scale if params.linear_scale else None}


class Measurements:
    """
    The measured signals of a run on the step grid, with the noise level that weights each.

    The residual of signal s at step k is (simulated - measured) / sigma_s;
    a signal with a free offset (:data:`OFFSET_SIGNALS`) has its mean residual
    removed (the offset's least-squares estimate); steps without a
    measurement (NaN: dropped or not sampled) give 0.

    Parameters
    ----------
    signals : dict
        name (of :data:`SIGNALS`) -> numpy array of the measured value after each
        step [unit], NaN where none.
    sigma : dict
        name -> noise level [unit] (> 0).

    """

    def __init__(self, signals, sigma):
        """Keep the signals in :data:`SIGNALS` order and their masks."""
        order = [s for s, _c, _u in SIGNALS if s in signals]
        self.names = order
        self.columns = {s: c for s, c, _u in SIGNALS}
        self.units = {s: u for s, _c, u in SIGNALS}
        self.data = np.array([np.asarray(signals[s], dtype=float) for s in order])
        self.mask = np.isfinite(self.data)
        self.data = np.where(self.mask, self.data, 0.0)
        self.sigma = {s: float(sigma[s]) for s in order}
        self.offset = [s in OFFSET_SIGNALS for s in order]

    @property
    def n(self):
        """Return the number of steps."""
        return self.data.shape[1]

    def differences(self, columns, n=None):
        """Return (simulated - measured) of the first n steps [unit], offsets removed."""
        n = self.n if n is None else n
        sim = np.array([np.asarray(columns[self.columns[s]], dtype=float)[:n]
                        for s in self.names])
        mask = self.mask[:, :n]
        d = np.where(mask, sim - self.data[:, :n], 0.0)
        for i, off in enumerate(self.offset):
            m = mask[i]
            if off and m.any():
                d[i, m] -= d[i, m].mean()
        return d

    def residuals(self, columns, n=None):
        """Return the weighted residual matrix (n_signals, n) of the first n steps."""
        w = np.array([1.0 / self.sigma[s] for s in self.names])
        return self.differences(columns, n) * w[:, None]

    def offsets_removed(self):
        """Return the number of offsets estimated (one per offset signal)."""
        return sum(self.offset)

    def rms(self, columns):
        """Return the RMS of each signal's differences from a re-simulation [unit]."""
        d = self.differences(columns)
        n = np.maximum(1, self.mask.sum(axis=1))
        return np.sqrt((d ** 2).sum(axis=1) / n)

    def reweight(self, columns, factor=REWEIGHT):
        """
        Raise the noise level of each signal the model explains only to a residual RMS above it.

        A signal whose residual RMS at the fit exceeds ``factor`` times its
        noise level carries a disturbance the re-simulation does not model
        (a drive loop's response to its sensor noise moves the motor off the
        noiseless path): its weight follows its RMS, so that it does not
        outweigh the signals the model explains. Returns the names raised.

        Parameters
        ----------
        columns : dict
            The re-simulation at the fit.
        factor : float
            Least rms / sigma that raises a signal's level.

        """
        raised = []
        for name, r in zip(self.names, self.rms(columns)):
            if r > factor * self.sigma[name]:
                self.sigma[name] = float(r)
                raised.append(name)
        return raised
