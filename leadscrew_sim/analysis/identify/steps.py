"""
Which recorded steps a fit compares, and from which state (no ROS, no I/O).

Slow plateaus (:func:`drop_slow`): steps of a commanded speed of a few
velocity quanta of the encoder, where the drive's limit cycle on its own
quantised feedback is not in the noiseless re-simulation, are left out.

Restarts at rests (multiple shooting, :class:`Anchoring`): a torque-mode
recording of stick-slip is a series of slides between rests. A compliant,
undamped coupling rings through every rest after a slide stops, and on the
next pulse the thread breaks away and sticks again on the crests of that
ringing, many times: a displacement of the motor by a thousandth of the
encoder's noise moves the slide's end by radians. A re-simulation from the
start then matches the recording only at the exact parameters, and a fit
has no basin to find. What it can match is each slide from the recorded
state at its start.

At a rest the state is fixed by what the sensors show: the screw and the
nut are stuck (no velocity), the drive applies no torque and holds no state
in torque mode, and the motor rings on the coupling about the screw's angle,
a linear free oscillation whose centre, displacement and rate the encoder
readings of the rest fix (:func:`ringing`). Away from the end stops the
dynamics are invariant under a translation of the screw and the nut
together, so the re-simulated state at the end of a rest is moved to the
recorded screw angle (both nut positions by the same lead: the thread's
contact gap is kept), its velocities are set to 0 and its motor to the
recorded ringing (:func:`anchor`). Each slide is then compared from its own
recorded start, but only as far as that start determines it
(:meth:`Anchoring.predictable`).

A rest (:func:`find_rests`) is the last :data:`REST_WINDOW` of a stretch of
torque commands of exactly 0 lasting :data:`REST_MIN` or more, in which the
scale reading stays within :data:`REST_SPREAD` noise levels and the encoder
readings are a free oscillation to within :data:`RING_FIT` noise levels.
Velocity and position mode have none: their loops' integrators are state
the sensors do not show.
"""
import dataclasses
import math

import numpy as np

from ...core.drive_modes import MODE_POSITION, MODE_TORQUE, MODE_VELOCITY
from . import linalg as la
from .lsq import least_squares

#: Least duration [s] of a stretch of zero torque that may hold a rest, and the window
#: [s] at its end in which the axis must rest.
REST_MIN, REST_WINDOW = 0.2, 0.15

#: Largest spread of the scale readings in a rest window, in noise levels.
REST_SPREAD = 8.0

#: Largest RMS residual of the encoder readings of a rest about a free oscillation, in
#: noise levels.
RING_FIT = 3.0


#: Commanded motor speed, in velocity quanta of the encoder through the drive period, below
#: which (and above 0) for at least SLOW_DWELL [s] a step's measurements are left out.
SLOW_QUANTA, SLOW_DWELL = 3.0, 0.1


def drop_slow(meas, commands, recorded, dt):
    """
    Leave out the steps of a slow commanded motion; return how many.

    The drive's velocity is the difference quotient of the encoder's readings
    over the drive period, so it moves in quanta of 2 pi / counts / period.
    At a commanded speed of a few quanta the loop acts on a reading that
    toggles between 0 and a quantum, and the recorded motion is the limit
    cycle of that loop, which the noiseless re-simulation does not have: there
    it pulls the friction toward values that mimic the cycle. Such steps
    (commanded motor speed above 0 and below :data:`SLOW_QUANTA` quanta: the
    velocity command, or the position command's rate, for at least
    :data:`SLOW_DWELL`, long enough for the cycle to build; a speed change
    passing through them is kept) carry no trustworthy information on the
    friction; a parameter only they would show is then judged on the rest.

    Parameters
    ----------
    meas : data.Measurements
        The measured signals; the steps left out leave its mask.
    commands : numpy.ndarray, shape (n, 4)
        The drive command rows of the steps.
    recorded : ScrewParams
        The recording's parameters (encoder counts, drive rate).
    dt : float
        The step [s].

    """
    quantum = 2.0 * math.pi / recorded.encoder_counts * recorded.drive_rate
    mode, pos, vel = (np.asarray(commands[:, i], dtype=float) for i in range(3))
    held = np.isfinite(mode)
    idx = np.maximum.accumulate(np.where(held, np.arange(len(mode)), 0))
    mode, pos, vel = mode[idx], pos[idx], vel[idx]
    rate = np.abs(np.gradient(pos, dt)) if len(pos) > 1 else np.zeros_like(pos)
    speed = np.where(mode == MODE_VELOCITY, np.abs(vel),
                     np.where(mode == MODE_POSITION, rate, 0.0))
    slow = (speed > 1e-12) & (speed < SLOW_QUANTA * quantum)
    edges = np.flatnonzero(np.diff(np.concatenate([[0], slow.astype(np.int8), [0]])))
    for a, b in zip(edges[::2], edges[1::2]):       # runs of slow steps [a, b)
        if (b - a) * dt < SLOW_DWELL:
            slow[a:b] = False
    n = min(len(slow), meas.n)
    meas.mask[:, :n] &= ~slow[None, :n]
    meas.data = np.where(meas.mask, meas.data, 0.0)
    return int(np.count_nonzero(slow[:n]))


@dataclasses.dataclass(frozen=True)
class Rest:
    """
    A rest of a recording: the steps ``a .. k`` and the recorded state after step ``k``.

    ``centre``: the encoder angle about which the motor rings (the screw's)
    [rad], theta sense, in the encoder's frame; the motor's displacement from
    it is e^(s t) (A cos(w t) + B sin(w t)) [rad], t [s] from the end of step
    ``k`` (:func:`ringing`); ``se_ring`` [rad], ``se_rate`` [rad/s]: the
    standard errors of the displacement and rate after step ``k``.
    """

    a: int
    k: int
    centre: float
    amp_a: float
    amp_b: float
    s: float
    w: float
    se_ring: float = 0.0
    se_rate: float = 0.0

    def displacement(self, t):
        """Return the motor's displacement from the centre [rad] at time ``t`` [s]."""
        return math.exp(self.s * t) * (self.amp_a * math.cos(self.w * t)
                                       + self.amp_b * math.sin(self.w * t))

    def motor(self, h):
        """
        Return the motor's (displacement [rad], rate [rad/s]) after step ``k`` as the model has it.

        The model's integrator moves a position by the substep ``h`` [s] times the
        new rate, so its rate is the difference quotient of the last substep.
        """
        u0 = self.displacement(0.0)
        return u0, (u0 - self.displacement(-h)) / h


def ringing(y, dt):
    """
    Return (centre, displacement, rate, rms) of a free oscillation fitted to samples ``y``.

    y_n = c + e^(s t_n) (A cos(w t_n) + B sin(w t_n)), t_n = (n - N + 1) dt
    (0 at the last sample); (s, w) start from the roots of the AR(2) model of
    the deviations from the mean (a sampled second-order linear oscillator
    is one exactly) and are refined by least squares with c, A, B solved
    linearly; without an oscillation (a rigid coupling) the fit is a constant.

    Parameters
    ----------
    y : numpy.ndarray
        The encoder readings of the rest [rad], every one measured.
    dt : float
        The sampling period [s].

    Returns
    -------
    tuple of float
        The centre c [rad], A and B [rad], s [1/s], w [rad/s] and the RMS
        residual of the fit [rad].

    """
    y = np.asarray(y, dtype=float)
    t = (np.arange(len(y)) - (len(y) - 1)) * dt
    c0 = float(np.mean(y))
    rms0 = float(np.sqrt(np.mean((y - c0) ** 2)))
    d = y - c0
    x = np.column_stack([d[1:-1], d[:-2]])
    sv = la.singular_values(x) if len(x) >= 2 else np.zeros(1)
    if rms0 == 0.0 or not sv[-1] > sv[0] * max(x.shape) * la.EPS:
        return c0, 0.0, 0.0, 0.0, 0.0, rms0
    a1, a2 = la.lstsq(x, d[2:])
    disc = 0.25 * a1 * a1 + a2          # roots of z^2 - a1 z - a2: complex for an oscillation
    if not disc < 0.0:
        return c0, 0.0, 0.0, 0.0, 0.0, rms0
    z = complex(0.5 * a1, math.sqrt(-disc))
    if abs(z) <= 0.0:
        return c0, 0.0, 0.0, 0.0, 0.0, rms0

    def basis(p):
        s, w = p
        e = np.exp(s * t)
        return np.column_stack([np.ones_like(t), e * np.cos(w * t), e * np.sin(w * t)])

    def resid(p):
        b = basis(p)
        return la.mat_vec(b, la.lstsq(b, y)) - y

    lo, hi = np.array([-0.1 / dt, 1e-3 / dt]), np.array([0.1 / dt, 0.999 * math.pi / dt])
    p0 = np.clip([math.log(abs(z)) / dt, math.atan2(z.imag, z.real) / dt], lo, hi)
    try:
        p = least_squares(resid, p0, lo, hi, math.sqrt(la.EPS), xtol=1e-14, ftol=1e-14,
                          gtol=1e-14, x_scale=np.array([1.0, p0[1]])).x
        c, amp_a, amp_b = la.lstsq(basis(p), y)
        rms = float(np.sqrt(np.mean(resid(p) ** 2)))
    except (ArithmeticError, ValueError):      # no oscillation to fit
        return c0, 0.0, 0.0, 0.0, 0.0, rms0
    if not rms < rms0:
        return c0, 0.0, 0.0, 0.0, 0.0, rms0
    return float(c), float(amp_a), float(amp_b), float(p[0]), float(p[1]), rms


def find_rests(commands, angle, sigma_angle, dt, position=None, sigma_position=None):
    """
    Return the :class:`Rest` s of a recording: where its state is fixed by its readings.

    Parameters
    ----------
    commands : numpy.ndarray, shape (n, 4)
        The drive command rows of the steps (mode, position, velocity, effort);
        a NaN mode holds the last row.
    angle : numpy.ndarray
        The encoder reading after each step [rad], NaN where none.
    sigma_angle : float
        Its noise level [rad].
    dt : float
        The step [s].
    position, sigma_position : numpy.ndarray and float, optional
        The scale reading after each step [m] (NaN where none) and its noise level.

    """
    mode, effort = np.asarray(commands[:, 0], dtype=float), np.asarray(commands[:, 3])
    held = np.isfinite(mode)
    idx = np.maximum.accumulate(np.where(held, np.arange(len(mode)), 0))
    zero = held[idx] & (mode[idx] == MODE_TORQUE) & (effort[idx] == 0.0)
    edges = np.flatnonzero(np.diff(np.concatenate([[0], zero.astype(np.int8), [0]])))
    need, window = int(round(REST_MIN / dt)), int(round(REST_WINDOW / dt))
    out = []
    for a, b in zip(edges[::2], edges[1::2]):       # runs of zero torque [a, b)
        if b - a < max(need, window) or b >= len(mode):   # short, or the run's end
            continue
        k = b - 1
        w0 = k - window + 1
        y = np.asarray(angle[w0:k + 1], dtype=float)
        if not np.isfinite(y).all():
            continue
        if position is not None and sigma_position:
            x = np.asarray(position[w0:k + 1], dtype=float)
            x = x[np.isfinite(x)]
            if not len(x) or x.max() - x.min() > REST_SPREAD * sigma_position:
                continue
        *fitted, rms = ringing(y, dt)
        if rms > RING_FIT * sigma_angle:
            continue
        # standard errors of the displacement and rate at the end: an oscillation's
        # amplitude from N samples of noise sigma is known to sigma sqrt(2 / N), its rate to
        # w times that
        se = sigma_angle * math.sqrt(2.0 / len(y))
        out.append(Rest(int(w0), int(k), *fitted, se, se * fitted[4]))
    return out


def anchor(model, rest, offset, kick=(0.0, 0.0)):
    """
    Move a model's state after step ``rest.k`` onto the recorded rest, in place.

    The screw angle becomes the recorded centre, the nut positions and the
    scale reading move with it through the lead (the contact gap is kept),
    the screw and nut velocities become 0 and the motor takes the recorded
    ringing about the screw (none through a rigid coupling).

    Parameters
    ----------
    model : LeadScrewModel
        The model, after step ``rest.k``.
    rest : Rest
        The rest.
    offset : float
        The encoder's reading less the re-simulated motor angle [rad] (theta
        sense): the zero of the encoder.
    kick : tuple of float
        Added to the motor's displacement [rad] and rate [rad/s] (a perturbation).

    """
    rigid = model.params.coupling_stiffness == 0.0
    ring, rate = (0.0, 0.0) if rigid else rest.motor(model.dt / model.nsub)
    model.place_at_rest(rest.centre - offset, ring + kick[0], rate + kick[1])


#: Relative steps of the intervals' Jacobian of a fit restarted at rests: below 1e-3 its
#: residuals jump (a breakaway one step earlier, on another crest of the ringing); the
#: slides' residuals stay linear in the friction to a few per cent.
RESTART_JAC_STEPS = (1e-3, 1e-2)

#: Standard errors of a rest's motor state by which :meth:`Anchoring.predictable` moves it:
#: the recorded state is within 3 of them but once in 370.
KICK = 3.0

#: Least steps of the first segment before its first breakaway that fix the encoder's zero.
ZERO_STEPS = 10


class Anchoring:
    """
    The re-simulation of a recording restarted at its rests, and the steps it can predict.

    Parameters
    ----------
    rests : list of Rest
        The recording's rests, in step order (:func:`find_rests`).
    angle : numpy.ndarray
        The encoder reading after each step [rad], NaN where none.

    """

    def __init__(self, rests, angle):
        """Keep the rests and the readings that fix the encoder's zero."""
        self.rests = list(rests)
        self.angle = np.asarray(angle, dtype=float)

    def cuts(self, n):
        """Return the first step of each segment after the first: one after each rest."""
        return [r.k + 1 for r in self.rests if 0 < r.k + 1 < n]

    def run(self, model, commands, forces, n=None, kicks=None, values=None):
        """
        Run the first ``n`` steps (all: None) through ``model``, anchored at each rest.

        The encoder's zero is the mean difference of the readings and the
        re-simulated angle over the first segment's steps before its first
        breakaway (all its steps if fewer than :data:`ZERO_STEPS`). Returns the
        columns of ``model.run``.

        Parameters
        ----------
        model : LeadScrewModel
            A new model at the recording's start.
        commands : numpy.ndarray, shape (n_steps, 4)
            The drive command rows (a NaN mode holds the model's command).
        forces : numpy.ndarray, shape (n_steps,)
            The external force of each step [N].
        n : int, optional
            The steps to run.
        kicks : dict, optional
            Rest index -> (displacement [rad], rate [rad/s]) added to its motor.
        values : iterable of str, optional
            Only these columns, and those the encoder's zero reads
            (``model.run``'s lean path; default all).

        """
        if values is not None:
            values = tuple(sorted(set(values) | {'sensor_screw_angle', 'stick_a'}))
        n = len(commands) if n is None else min(n, len(commands))
        rows = np.array(commands[:n], dtype=float)
        held = np.isnan(rows[:, 0])
        if held.any():
            rows[held] = model.held_command()
        cuts = self.cuts(len(commands))
        parts, a, offset = [], 0, 0.0
        for j, b in enumerate([c for c in cuts if c < n] + [n]):
            if j > 0:
                anchor(model, self.rests[j - 1], offset, (kicks or {}).get(j - 1, (0.0, 0.0)))
            if b > a:
                parts.append(model.run(None, forces[a:b], commands=rows[a:b], values=values))
            if j == 0:
                offset = self._zero(parts[0]) if parts else 0.0
            a = b
        return {k: np.concatenate([p[k] for p in parts]) for k in parts[0]} if parts else {}

    def _zero(self, cols):
        """Return the encoder's reading less the re-simulated angle [rad] (see :meth:`run`)."""
        sim = np.asarray(cols['sensor_screw_angle'], dtype=float)
        stuck = np.asarray(cols['stick_a']) == 1
        m = len(sim) if stuck.all() else int(np.argmin(stuck))
        if m < ZERO_STEPS:
            m = len(sim)
        d = self.angle[:m] - sim[:m]
        d = d[np.isfinite(d)]
        return float(d.mean()) if len(d) else 0.0

    def predictable(self, make_model, commands, forces, signals):
        """
        Return the steps whose re-simulation the rests determine to within the noise.

        A segment after a rest is compared up to the first step at which a
        re-simulation with that rest's motor displacement, or its rate, off by
        :data:`KICK` standard errors differs from the anchored one by more than a
        signal's noise level: beyond it the recorded state does not determine
        the motion (a breakaway on the crest of the ringing a step earlier or
        later, stick-slip that follows). The first segment starts from the
        model's initial state, as the recording does, and is compared whole.

        Parameters
        ----------
        make_model : callable
            ``make_model() -> LeadScrewModel``: a new model of the values judged.
        commands, forces : numpy.ndarray
            As :meth:`run`.
        signals : list of (str, float)
            The ``model.run`` column and noise level [unit] of each compared signal.

        Returns
        -------
        numpy.ndarray of bool, shape (n_steps,)

        """
        n = len(commands)
        keep = np.ones(n, dtype=bool)
        if not self.rests:
            return keep
        base = self.run(make_model(), commands, forces)
        edges = [0] + self.cuts(n) + [n]
        for which in (0, 1):
            kicks = {j: (KICK * r.se_ring, 0.0) if which == 0 else (0.0, KICK * r.se_rate)
                     for j, r in enumerate(self.rests)}
            other = self.run(make_model(), commands, forces, kicks=kicks)
            off = np.zeros(n, dtype=bool)
            for col, sigma in signals:
                off |= ~(np.abs(np.asarray(other[col]) - np.asarray(base[col])) <= sigma)
            for a, b in zip(edges[1:-1], edges[2:]):
                first = np.flatnonzero(off[a:b])
                if len(first):
                    keep[a + first[0]:b] = False
        return keep


def anchoring_of(meas, commands, dt):
    """
    Return the :class:`Anchoring` of measured signals (None without a rest).

    Parameters
    ----------
    meas : data.Measurements
        The measured signals (an encoder angle, optionally a scale position).
    commands : numpy.ndarray, shape (n, 4)
        The drive command rows of the steps.
    dt : float
        The step [s].

    """
    if 'screw_angle' not in meas.names:
        return None
    rows = {s: np.where(meas.mask[i], meas.data[i], np.nan) for i, s in enumerate(meas.names)}
    rests = find_rests(commands[:meas.n], rows['screw_angle'], meas.sigma['screw_angle'], dt,
                       rows.get('nut_position'), meas.sigma.get('nut_position'))
    return Anchoring(rests, rows['screw_angle']) if rests else None
