"""
The step-sampled response when a step is not a whole number of drive periods (lifting).

With drive period T_d and step T, T / T_d = A / B in lowest terms: every B
steps (A drive updates) the timing repeats. Over such a block the axis is a
linear map of the state at the block's start and of the B held inputs; for
an input u_i = e^(jw t_i) (held over step i, t_i its end) the periodic
steady state is exact, and the response a measurement over whole blocks
sees is the first harmonic of the outputs at the step ends,
H = (1 / B) sum_i y_i e^(-jw t_i). The events of a block: the drive updates
(at k T_d, reading the state, holding the torque) and the steps' boundaries
(the input changes), the plant's exact zero-order hold between them.
"""
from fractions import Fraction
import math

import numpy as np

from .discrete import zoh

__all__ = ['block_ratio', 'lifted_response']


def block_ratio(dt, td, limit=1000):
    """Return (A, B): T / T_d = A / B in lowest terms (denominator at most ``limit``)."""
    r = Fraction(dt / td).limit_denominator(limit)
    return r.numerator, r.denominator


def _maps(drv, td):
    """Return (Ac, bc, U, v): the held-torque dynamics over X, the update X <- U X + v u."""
    pl, n, nx = drv.pl, drv.n, drv.nx
    m = n + 2                                # [x_p, I, T_h, e_h]
    ac = np.zeros((m, m))
    ac[:nx, :nx] = pl.a
    ac[:nx, n] = pl.b_t                      # the plant runs on the held torque
    bc = np.zeros((m, 1))
    bc[:nx, 0] = pl.b_f * drv.force
    u = np.eye(m)
    v = np.zeros(m)
    if drv.integral:
        u[nx, :n] += td * drv.e[0]
        v[nx] = td * drv.e[1]
    u[n] = 0.0
    u[n, :n] = drv.t_c[0]
    v[n] = drv.t_c[1]
    u[n + 1] = 0.0
    u[n + 1, :n] = drv.q_ref[0] - drv.q_fb[0]
    v[n + 1] = drv.q_ref[1] - drv.q_fb[1]
    return ac, bc, u, v


def _events(a, b, dt, td):
    """Return the block's events in order: (update, step), (run, tau, step), (end, step)."""
    out = []
    times = sorted({k * td for k in range(a)} | {i * dt for i in range(b + 1)})
    block = b * dt
    for t0, t1 in zip(times[:-1], times[1:]):
        step = min(b - 1, int(math.floor(t0 / dt + 1e-9)))
        k = t0 / td
        if abs(k - round(k)) < 1e-9 and round(k) < a:
            out.append(('update', step))
        out.append(('run', t1 - t0, step))
        if abs(t1 / dt - round(t1 / dt)) < 1e-9:
            out.append(('end', int(round(t1 / dt)) - 1))
    assert abs(times[-1] - block) < 1e-9 * block
    return out


def lifted_response(drv, c, d, frequency, dt, td):
    """
    Return H at the frequencies [Hz] as a run at step dt measures it (see the module doc).

    Parameters
    ----------
    drv : linear._Drive
        The drive's expressions (mode, input).
    c, d : numpy.ndarray, float
        The output's row over [x_p, I, T_h, e_h] and its coefficient on u.
    frequency : array_like
        [Hz].
    dt, td : float
        Step and drive period [s].

    """
    a, b = block_ratio(dt, td)
    ac, bc, upd, v = _maps(drv, td)
    events = _events(a, b, dt, td)
    cache = {}
    for ev in events:
        if ev[0] == 'run' and round(ev[1] / td * 1e6) not in cache:
            cache[round(ev[1] / td * 1e6)] = zoh(ac, bc, ev[1])
    out = []
    m = len(v)
    for f in np.atleast_1d(np.asarray(frequency, float)):
        w = 2.0 * math.pi * f
        u = np.exp(1j * w * dt * np.arange(1, b + 1))      # input of each step
        p, q = np.eye(m, dtype=complex), np.zeros(m, dtype=complex)
        ys = []
        for ev in events:                    # x = p x0 + q through the block
            if ev[0] == 'update':
                p, q = upd @ p, upd @ q + v * u[ev[1]]
            elif ev[0] == 'run':
                e, g = cache[round(ev[1] / td * 1e6)]
                p, q = e @ p, e @ q + g[:, 0] * u[ev[2]]
            else:
                ys.append((ev[1], p.copy(), q.copy()))
        x0 = np.linalg.solve(np.exp(1j * w * b * dt) * np.eye(m) - p, q)
        y = [(c @ (pp @ x0 + qq) + d * u[i]) * np.exp(-1j * w * dt * (i + 1))
             for i, pp, qq in ys]
        out.append(sum(y) / b)
    return np.array(out)
