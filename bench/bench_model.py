"""
Benchmark the physics core: ns per substep, real-time factor, and LSODA side by side.

Run: make bench   (or: .venv/bin/python bench/bench_model.py [--seconds 20])
Prints, in one run on this machine, for each preset at dt = 1 ms, no I/O, under three
drives (zero torque: holding; a PD position loop tracking a sine: moving, reversing;
the servo drive in position mode tracking the same sine):
- ns per substep (the full model: backlash + stiction + anti-backlash preset), and for
  the servo drive its ratio to the torque-mode track drive;
- simulated seconds per wall second, per tick call and in one batch call;
- the same smooth case integrated by our kernel and by scipy's solve_ivp (LSODA),
  with the wall time ratio.
"""
import argparse
import math
import time

import numpy as np
from scipy.integrate import solve_ivp

from leadscrew_sim.core.engine import drive as D, kernel as K, layout as L
from leadscrew_sim import LeadScrewModel, load_preset, preset_names


def track_torques(params, sim_seconds, dt=1e-3, amplitude=0.05, freq=0.5, bandwidth=20.0):
    """
    Motor torques [N m] of a PD loop on the motor angle tracking x = A sin(2 pi f t).

    The loop runs once through the model (tick by tick); the returned torques
    replay the same trajectory bit for bit (the model is deterministic), so the
    timed runs below measure the kernel alone, on an axis that moves, reverses
    and sticks as under a real position controller.
    """
    m = LeadScrewModel(params, dt=dt)
    P = m._P
    rt = P[L.P_RT]
    j = params.motor_inertia + params.screw_inertia + \
        (params.nut_mass + params.payload_mass) * rt ** 2
    w = 2 * math.pi * bandwidth
    kp, kd = j * w * w, 2 * 0.7 * w * j
    n = int(sim_seconds / dt)
    out = np.empty(n)
    for i in range(n):
        q_ref = amplitude * math.sin(2 * math.pi * freq * (i * dt)) / rt    # q sense
        t_q = kp * (q_ref - m.state[L.S_QM]) - kd * m.state[L.S_WM]
        t_q = min(max(t_q, -params.max_torque), params.max_torque)
        out[i] = params.hand_sign * t_q
        m.advance(out[i])
    return out


def kernel_rate(params, torques, dt=1e-3, block=1000, repeats=3):
    """
    Return (ns per substep, sim s per wall s, nsub, batch ns, batch x, stuck share).

    Per-tick: one kernel call per 1 ms tick from Python (as the node does).
    Batch: model.run() on blocks of `block` ticks (as simulate does). Each is
    the best of `repeats` runs, to take the shared machine's stalls out.
    """
    m = LeadScrewModel(params, dt=dt)
    n = len(torques)
    sim_seconds = n * dt
    tq_q = params.hand_sign * torques
    m.run(torques[:2])                     # compile, warm up both paths
    K.step(m._P, m.state, m.out, 0.0, 0.0, dt, m.nsub, m._wk, m._iwk)
    wall = batch = math.inf
    for _ in range(repeats):
        m.reset()
        t0 = time.perf_counter()
        for tq in tq_q:
            K.step(m._P, m.state, m.out, tq, 0.0, dt, m.nsub, m._wk, m._iwk)
        wall = min(wall, time.perf_counter() - t0)
        m.reset()
        stuck = 0
        t0 = time.perf_counter()
        for i in range(0, n, block):
            stuck += int(np.count_nonzero(m.run(torques[i:i + block])['stuck']))
        batch = min(batch, time.perf_counter() - t0)
    return wall / (n * m.nsub) * 1e9, sim_seconds / wall, m.nsub, \
        batch / (n * m.nsub) * 1e9, sim_seconds / batch, stuck / n


def drive_commands(params, sim_seconds, dt=1e-3, amplitude=0.05, freq=0.5):
    """
    Command rows of the servo drive in position mode tracking x = A sin(2 pi f t).

    Theta sense (mode, motor angle target, velocity feed-forward, no torque
    feed-forward), through the model's lead mapping; the target of each step is
    the trajectory at its end.
    """
    m = LeadScrewModel(params, dt=dt)
    n = int(sim_seconds / dt)
    t = (np.arange(n) + 1) * dt
    w = 2 * math.pi * freq
    rows = np.empty((n, 4))
    rows[:, 0] = D.MODE_POSITION
    rows[:, 1] = m.nut_to_motor(amplitude * np.sin(w * t))
    rows[:, 2] = m.nut_to_motor(amplitude * w * np.cos(w * t)) - m.nut_to_motor(0.0)
    rows[:, 3] = math.nan
    return rows


def drive_rate(params, rows, dt=1e-3, block=1000, repeats=3):
    """
    Return kernel_rate's figures for the servo drive following command rows (theta sense).

    Per-tick: the held target and feed-forward written into the state (two
    float stores, as model.command leaves them), then one step_held call per
    tick; batch: model.run(None, commands=...) on blocks of `block` ticks.
    """
    m = LeadScrewModel(params, dt=dt)
    n = len(rows)
    sim_seconds = n * dt
    q_rows = D.command_rows(rows, params.hand_sign)   # q sense, as model.command stores them
    targets = list(zip(q_rows[:, 1].tolist(), q_rows[:, 2].tolist()))
    m.run(None, commands=rows[:2])             # compile, warm up both paths
    K.step_held(m._P, m.state, m.out, 0.0, dt, m.nsub, m._wk, m._iwk)
    wall = batch = math.inf
    s = m.state
    for _ in range(repeats):
        m.reset()
        m.command(D.MODE_POSITION, position=rows[0, 1])
        t0 = time.perf_counter()
        for q, w in targets:
            s[L.S_CQ] = q
            s[L.S_CW] = w
            K.step_held(m._P, s, m.out, 0.0, dt, m.nsub, m._wk, m._iwk)
        wall = min(wall, time.perf_counter() - t0)
        m.reset()
        stuck = 0
        t0 = time.perf_counter()
        for i in range(0, n, block):
            stuck += int(np.count_nonzero(m.run(None, commands=rows[i:i + block])['stuck']))
        batch = min(batch, time.perf_counter() - t0)
    return wall / (n * m.nsub) * 1e9, sim_seconds / wall, m.nsub, \
        batch / (n * m.nsub) * 1e9, sim_seconds / batch, stuck / n


def lsoda_side_by_side(sim_seconds):
    """Integrate the same smooth sliding case with our kernel and with LSODA."""
    p = load_preset('tr8x8').replace(mu_s=0.12, mu_k=0.12, mu_viscous=0.5,
                                     bearing_viscous=2e-4, stroke_min=-10.0, stroke_max=10.0)
    tq = -0.04
    m = LeadScrewModel(p, dt=1e-3)
    y0 = m.state[[L.S_Q, L.S_DQ, L.S_XA, L.S_VA]].copy()
    t0 = time.perf_counter()
    for _ in range(int(sim_seconds / 1e-3)):
        K.step(m._P, m.state, m.out, p.hand_sign * tq, 0.0, 1e-3, m.nsub, m._wk, m._iwk)
    ours = time.perf_counter() - t0
    lam = p.lead_angle
    rm, sl, cl = p.r_m, math.sin(lam), math.cos(lam)
    rt, j = rm * math.tan(lam), p.motor_inertia + p.screw_inertia
    mass, k, c, hb = p.nut_mass + p.payload_mass, p.contact_stiffness, p.contact_damping, \
        p.backlash / 2
    tq_q = p.hand_sign * tq

    def rhs(t, y):
        q, dq, x, v = y
        d, dd = x - rt * q, v - rt * dq
        pl = max(0.0, k * (-d - hb) - c * dd) if -d - hb > 0 else 0.0
        pu = max(0.0, k * (d - hb) + c * dd) if d - hb > 0 else 0.0
        vs = rm * dq * cl + v * sl
        mu = (p.mu_k + p.mu_viscous * abs(vs)) * p.thread_factor
        ff = -mu * (pl + pu) / cl * np.sign(vs)
        n = (pl - pu) / cl
        return [dq, (tq_q - p.bearing_viscous * dq + rm * (-n * sl + ff * cl)) / j,
                v, (n * cl + ff * sl - mass * p.gravity - p.guide_viscous * v) / mass]
    t0 = time.perf_counter()
    sol = solve_ivp(rhs, (0, sim_seconds), y0, method='LSODA', rtol=1e-6, atol=1e-9)
    lsoda = time.perf_counter() - t0
    dx = abs(sol.y[2, -1] - m.state[L.S_XA])
    return ours, lsoda, dx, sol.nfev


def main():
    """Run the benchmark and print a table."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[1])
    ap.add_argument('--seconds', type=float, default=20.0, help='simulated s per preset')
    args = ap.parse_args()
    print('per-step call = one kernel call per 1 ms tick (as the node does);')
    print('batch = model.run() on 1 s blocks, 1000 ticks per compiled call (as simulate does)')
    print('each column: best of 3 runs')
    print('hold = zero torque; track = PD position loop, x = 50 mm sin(2 pi 0.5 Hz t);')
    print('servo = the servo drive in position mode (velocity feed-forward) tracking the same;')
    print('servo/track: its ns per substep over the track drive\'s (per-step call, batch)')
    print(f'{"preset":<15}{"drive":<7}{"substeps/ms":>12}{"ns/substep":>12}{"x real time":>13}'
          f'{"batch ns/sub":>14}{"batch x rt":>12}{"stuck %":>9}{"servo/track":>13}')
    n = int(args.seconds / 1e-3)
    for name in preset_names():
        p = load_preset(name)
        if p.drive_type == 'stepper':   # no torque input: bench/bench_stepper.py measures it
            print(f'{name:<15}(a stepper: see bench/bench_stepper.py)')
            continue
        figures = {}
        for drive, torques in (('hold', np.zeros(n)), ('track', track_torques(p, args.seconds)),
                               ('servo', None)):
            if torques is None:
                figures[drive] = drive_rate(p, drive_commands(p, args.seconds))
            else:
                figures[drive] = kernel_rate(p, torques)
            ns, rtf, nsub, bns, brtf, stuck = figures[drive]
            ratio = ''
            if drive == 'servo':
                ratio = f'{ns / figures["track"][0]:.2f} {bns / figures["track"][3]:.2f}'
            print(f'{name:<15}{drive:<7}{nsub:>12}{ns:>12.1f}{rtf:>13.0f}{bns:>14.1f}'
                  f'{brtf:>12.0f}{100 * stuck:>9.1f}{ratio:>13}')
    ours, lsoda, dx, nfev = lsoda_side_by_side(min(args.seconds, 5.0))
    print(f'\nsmooth case, {min(args.seconds, 5.0)} s simulated: kernel {ours:.3f} s wall, '
          f'LSODA {lsoda:.3f} s wall ({nfev} RHS calls), ratio LSODA/kernel '
          f'{lsoda / ours:.1f}x, final |dx| {dx:.2e} m')


if __name__ == '__main__':
    main()
