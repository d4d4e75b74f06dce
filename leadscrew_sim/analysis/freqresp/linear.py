"""
The linear frequency response: the plant under its drive, continuous and sampled.

See doc/frequency_response.md ("The linear model").

Inputs (user senses, SI): ``torque`` (motor torque command [N m], theta
sense, torque mode: no loop), ``velocity_command`` (nut velocity [m/s],
velocity loop closed), ``position_command`` (nut position [m], position and
velocity loops closed), ``external_force`` (axial force on the nut [N], +x,
under the drive mode ``mode``, default position). Outputs: ``motor_angle``
[rad], ``motor_velocity`` [rad/s] (theta sense), ``nut_position`` [m],
``nut_velocity`` [m/s], ``thread_force`` (axial force of the screw on the nut
[N]), ``following_error`` (theta_ref - theta_fb [rad], position mode only),
``motor_torque`` (applied, theta sense [N m]). Loop quantities at the
velocity (position) controller's summing point, the injection between
controller and plant: L = C P, S = 1 / (1 + L), T = L / (1 + L).

Three samplings (:data:`SAMPLINGS`):

- ``continuous``: the drive as a continuous PI (+ P) loop, H(jw) = C (jw I - A)^-1 B + D;
- ``drive``: the drive as it runs, sampled at its period T_d with the torque
  held (the plant's exact zero-order-hold discretisation), the command held
  over each drive period; the loops' figures of doc/model.md are on this;
- ``step``: what a simulation or recording at the step T measures: the
  command held over each step, the output sampled at the step's end and
  paired with the input held over the step that ends there (the stamps'
  alignment): H(z) = C (I - Phi z^-1)^-1 Gamma + D, z = e^(jwT). Exact when
  T is a whole number of drive periods; else exact over the block of steps
  after which the timing repeats (:mod:`.lifted`).

The drive reads ideal sensors (the true motor angle and rate, or the nut
position through the lead for ``drive_feedback: linear_scale``).
"""
from dataclasses import dataclass
import math

import numpy as np
from scipy.linalg import eigvals

from ...core.drive_control import drive_period
from ...core.params import ParameterError
from .discrete import zoh
from .plant import plant

__all__ = ['closed_loop', 'ClosedLoop', 'INPUTS', 'LinearSystem', 'LOOPS', 'MODES', 'OUTPUTS',
           'QUANTITIES', 'SAMPLINGS', 'zoh']

INPUTS = ('torque', 'velocity_command', 'position_command', 'external_force')
OUTPUTS = ('motor_angle', 'motor_velocity', 'nut_position', 'nut_velocity', 'thread_force',
           'following_error', 'motor_torque')
LOOPS = ('velocity', 'position')
QUANTITIES = ('L', 'S', 'T')
SAMPLINGS = ('continuous', 'drive', 'step')
MODES = ('torque', 'velocity', 'position')
#: The drive mode of each input (external_force: the ``mode`` asked for).
INPUT_MODES = {'torque': 'torque', 'velocity_command': 'velocity',
               'position_command': 'position'}


@dataclass
class LinearSystem:
    """
    A SISO state space: continuous (period 0) or sampled with the stamps' pairing.

    Continuous: X' = A X + B u, y = C X + D u. Sampled (period T > 0):
    X_k = A X_(k-1) + B u_k (u_k held over the period ending at k), y_k = C X_k + D u_k.
    """

    a: np.ndarray
    b: np.ndarray
    c: np.ndarray
    d: float
    period: float = 0.0

    def response(self, frequency):
        """Return H at the frequencies [Hz] (complex, output unit over input unit)."""
        f = np.atleast_1d(np.asarray(frequency, dtype=float))
        n = len(self.b)
        eye = np.eye(n)
        out = np.empty(len(f), dtype=complex)
        for i, fi in enumerate(f):
            w = 2.0 * math.pi * fi
            if self.period > 0.0:
                m = eye - self.a * np.exp(-1j * w * self.period)
            else:
                m = 1j * w * eye - self.a
            out[i] = self.c @ np.linalg.solve(m, self.b) + self.d
        return out

    def poles(self):
        """Return the poles [1/s] (continuous; a sampled system's mapped by log(z) / T)."""
        return _to_s(np.linalg.eigvals(self.a), self.period)

    def zeros(self):
        """Return the finite transmission zeros [1/s] (sampled: log(z) / T)."""
        n = len(self.b)
        big = np.block([[self.a, self.b[:, None]], [self.c[None, :], np.array([[self.d]])]])
        e = np.zeros((n + 1, n + 1))
        e[:n, :n] = np.eye(n)
        if self.period > 0.0:                # zeros of C (zI - A)^-1 B z + D ... in z
            big[:n, n] = self.a @ self.b
            big[n, n] = self.c @ self.b + self.d
        z = eigvals(big, e)
        z = z[np.isfinite(z)]
        return _to_s(z[np.abs(z) < 1e12], self.period)


def _to_s(z, period):
    if period <= 0.0:
        return z
    z = z[np.abs(z) > 0.0]
    return np.log(z.astype(complex)) / period


def _check(name, value, allowed):
    if value not in allowed:
        raise ParameterError(name, f'{value!r} is not one of {", ".join(allowed)}')


class _Drive:
    """The drive's signals as linear expressions (row over [x_p, I], coefficient on u)."""

    def __init__(self, p, pl, mode, where):
        self.p, self.pl, self.mode = p, pl, mode
        self.nx = len(pl.a)
        self.integral = mode != 'torque' and p.velocity_integral_time > 0.0
        self.n = self.nx + (1 if self.integral else 0)
        rt, hs = p.lead_ratio, p.hand_sign
        gain = dict(torque=hs, velocity_command=1.0 / rt, position_command=1.0 / rt,
                    external_force=1.0, t_ff=1.0, w_ff=1.0)[where]
        self.u = {k: (gain if k == where else 0.0) for k in
                  ('torque', 'velocity_command', 'position_command', 'external_force',
                   't_ff', 'w_ff')}
        row = self.plant_row
        scale = p.drive_feedback == 'linear_scale'
        self.q_fb = (row('x')[0] / rt, 0.0) if scale else (row('q_m')[0], 0.0)
        self.w_fb = (row('w_m')[0], 0.0)
        zero = np.zeros(self.n)
        self.q_ref = (zero, self.u['position_command'])
        if mode == 'position':
            kp = p.position_gain
            w_ref = (-kp * self.q_fb[0], kp * self.u['position_command'] + self.u['w_ff'])
        else:
            w_ref = (zero.copy(), self.u['velocity_command'] + self.u['w_ff'])
        self.w_ref = w_ref
        self.e = (w_ref[0] - self.w_fb[0], w_ref[1])
        if mode == 'torque':
            self.t_c = (zero.copy(), self.u['torque'])
        else:
            kv, ti = p.velocity_gain, p.velocity_integral_time
            t_row = kv * self.e[0]
            if self.integral:
                t_row[-1] += kv / ti
            self.t_c = (t_row, kv * self.e[1] + self.u['t_ff'])
        self.force = self.u['external_force']

    def plant_row(self, name):
        """Return a plant row (over [x_p, I]) and its coefficients on T_c and F."""
        r, ct, cf = self.pl.rows[name]
        out = np.zeros(self.n)
        out[:self.nx] = r
        return out, ct, cf

    def continuous(self):
        """Return (A, B) of the loop closed with the continuous PI (+ P)."""
        pl, n, nx = self.pl, self.n, self.nx
        a = np.zeros((n, n))
        b = np.zeros(n)
        a[:nx, :nx] = pl.a
        a[:nx] += np.outer(pl.b_t, self.t_c[0])
        b[:nx] = pl.b_t * self.t_c[1] + pl.b_f * self.force
        if self.integral:
            a[-1] = self.e[0]
            b[-1] = self.e[1]
        return a, b

    def output(self, name):
        """Return (row, coefficient on u) of an output in the continuous closed loop."""
        hs = self.p.hand_sign
        if name == 'following_error':
            if self.mode != 'position':
                raise ParameterError('output', 'following_error needs the position loop '
                                     '(input position_command, or external_force with mode '
                                     'position)')
            return hs * (self.q_ref[0] - self.q_fb[0]), hs * (self.q_ref[1] - self.q_fb[1])
        key, sign = dict(motor_angle=('q_m', hs), motor_velocity=('w_m', hs),
                         nut_position=('x', 1.0), nut_velocity=('v', 1.0),
                         thread_force=('force', 1.0), motor_torque=('torque', hs))[name]
        r, ct, cf = self.plant_row(key)
        return sign * (r + ct * self.t_c[0]), sign * (ct * self.t_c[1] + cf * self.force)

    def sampled(self, td):
        """Return (A, B) of one drive period [s]: X = [x_p, I, T_h, e_h], pairing at its end."""
        pl, n, nx = self.pl, self.n, self.nx
        phi, gam = zoh(pl.a, np.column_stack([pl.b_t, pl.b_f]), td)
        m = n + 2                            # + the held torque and following error
        a = np.zeros((m, m))
        b = np.zeros(m)
        a[:nx, :nx] = phi
        a[:nx, :n] += np.outer(gam[:, 0], self.t_c[0])
        b[:nx] = gam[:, 0] * self.t_c[1] + gam[:, 1] * self.force
        if self.integral:
            a[nx, :n] = td * self.e[0]
            a[nx, nx] += 1.0
            b[nx] = td * self.e[1]
        a[n, :n] = self.t_c[0]
        b[n] = self.t_c[1]
        a[n + 1, :n] = self.q_ref[0] - self.q_fb[0]
        b[n + 1] = self.q_ref[1] - self.q_fb[1]
        return a, b

    def sampled_output(self, name):
        """Return (row over the sampled state, coefficient on u) of an output."""
        hs = self.p.hand_sign
        n = self.n
        row = np.zeros(n + 2)
        if name == 'following_error':
            self.output(name)                # the same check
            row[n + 1] = hs
            return row, 0.0
        key, sign = dict(motor_angle=('q_m', hs), motor_velocity=('w_m', hs),
                         nut_position=('x', 1.0), nut_velocity=('v', 1.0),
                         thread_force=('force', 1.0), motor_torque=('torque', hs))[name]
        r, ct, cf = self.plant_row(key)
        row[:n] = r
        row[n] += ct                          # the torque held over the period just ended
        return sign * row, sign * cf * self.force


def _steps_per_period(p, dt, td):
    """Return N = dt / td rounded, and whether it is whole (within 1e-9)."""
    ratio = dt / td
    k = max(1, int(round(ratio)))
    return k, abs(ratio - k) < 1e-9 * ratio


class ClosedLoop:
    """
    The linearised axis from one input to one output: its systems and their responses.

    Parameters
    ----------
    params : ScrewParams
        The axis.
    input, output : str
        Names of :data:`INPUTS` and :data:`OUTPUTS`.
    speed : float
        Nut speed of the operating point [m/s]; 0: at rest on the loaded flank.
    mode : str, optional
        Drive mode for ``external_force`` (default 'position'); else the input's own.
    rest : str
        At rest: 'stuck' or 'free' thread (:func:`.plant.plant`).

    """

    def __init__(self, params, input, output, speed=0.0, mode=None, rest='stuck'):
        """Build the plant and the drive's expressions (see the class doc)."""
        _check('input', input, INPUTS)
        _check('output', output, OUTPUTS)
        if mode is not None:
            _check('mode', mode, MODES)
        if input != 'external_force':
            mode = INPUT_MODES[input]
        self.params, self.input, self.output, self.speed = params, input, output, speed
        self.mode = mode or 'position'
        self.plant = plant(params, speed, rest)
        self.drive = _Drive(params, self.plant, self.mode, input)
        self.drive.output(output)            # refuses a following error without its loop

    def system(self, sampling='continuous', dt=1e-3):
        """Return the :class:`LinearSystem` of a sampling ('continuous' or 'drive')."""
        _check('sampling', sampling, SAMPLINGS[:2])
        if sampling == 'continuous':
            a, b = self.drive.continuous()
            c, d = self.drive.output(self.output)
            return LinearSystem(a, b, c, d)
        td = drive_period(self.params, dt)
        a, b = self.drive.sampled(td)
        c, d = self.drive.sampled_output(self.output)
        return LinearSystem(a, b, c, d, td)

    def step_system(self, dt):
        """Return the system sampled at the step dt [s] if whole drive periods, else None."""
        td = drive_period(self.params, dt)
        k, whole = _steps_per_period(self.params, dt, td)
        if self.mode == 'torque':
            k, whole, td = 1, True, dt
        if not whole:
            return None
        a, b = self.drive.sampled(td)
        a_k = np.linalg.matrix_power(a, k)
        b_k = sum(np.linalg.matrix_power(a, i) @ b for i in range(k))
        c, d = self.drive.sampled_output(self.output)
        return LinearSystem(a_k, b_k, c, d, dt)

    def response(self, frequency, sampling='continuous', dt=1e-3):
        """Return (H at the frequencies [Hz], notes) for a sampling of :data:`SAMPLINGS`."""
        _check('sampling', sampling, SAMPLINGS)
        f = np.asarray(frequency, dtype=float)
        if sampling != 'step':
            note = ('continuous drive (PI + P loops without sampling)' if sampling == 'continuous'
                    else f'drive sampled at {1.0 / drive_period(self.params, dt):.6g} Hz, '
                    'torque held')
            return self.system(sampling, dt).response(f), [note]
        sys_k = self.step_system(dt)
        if sys_k is not None:
            return sys_k.response(f), [f'exact zero-order hold at the {1.0 / dt:.6g} Hz step, '
                                       'output at the step end (stamps aligned)']
        from .lifted import block_ratio, lifted_response
        td = drive_period(self.params, dt)
        c, d = self.drive.sampled_output(self.output)
        a, b = block_ratio(dt, td)
        return lifted_response(self.drive, c, d, f, dt, td), [
            f'step {dt:g} s = {a}/{b} drive periods ({td:.6g} s): the periodic steady state '
            f'over {b} steps, first harmonic at the step ends (stamps aligned)']


def closed_loop(params, input, output, speed=0.0, mode=None, rest='stuck'):
    """Return the :class:`ClosedLoop` from ``input`` to ``output`` (see the class)."""
    return ClosedLoop(params, input, output, speed, mode, rest)
