"""
Low-speed resonance of the stepper: full steps against 16 microsteps (doc/model.md section 18).

Oracle: the rotor's small-signal natural frequency f_n = sqrt(N_r (T_h + 4
T_d) / J_total) / (2 pi) (J_total with the screw and the nut through the
lead). Full steps kick the rotor once per step, so stepping at f_n full
steps/s drives that mode at resonance: the rotor's swing about its mean
motion is larger there than at half or twice the rate (it may grow until the
rotor slips a cycle). 16 microsteps turn
the kicks into a near-sinusoidal field rotation: the swing at the same rate
is a small fraction of the full-step one. The two swings are printed.
"""
import math

import numpy as np

from leadscrew_sim import LeadScrewModel, load_preset
from stepper_axes import motor_inertia_total, velocity_rows


def swing(p, rate, dt=1e-4, seconds=0.6):
    """
    Return (the rotor's swing about its mean motion [full steps], the full steps lost).

    Raising at ``rate`` full steps/s; the swing is measured from 0.25 to 0.5 s
    (after the start's transient), where no step may have been lost yet; a
    resonance may make the rotor slip later.
    """
    m = LeadScrewModel(p, dt=dt)
    n = int(round(seconds / dt))
    r = m.run(None, commands=velocity_rows(n, p.hand_sign * rate * p.step_angle))
    window = slice(int(round(0.25 / dt)), int(round(0.5 / dt)))
    assert not r['lost_full_steps'][:window.stop].any(), rate
    t = np.arange(n)[window] * dt
    theta = r['motor_angle'][window]
    err = theta - np.polyval(np.polyfit(t, theta, 1), t)
    return 0.5 * (err.max() - err.min()) / p.step_angle, int(r['lost_full_steps'][-1])


def test_full_steps_resonate_at_the_natural_frequency_microsteps_do_not():
    """At f_n full steps/s the full-step swing peaks; 16 microsteps swing < 1/10 of it."""
    p = load_preset('nema17_tr8x8', microsteps=1, hold_current_delay=10.0)
    f_n = math.sqrt(p.rotor_teeth * (p.holding_torque + 4.0 * p.detent_torque)
                    / motor_inertia_total(p)) / (2.0 * math.pi)
    full, lost = swing(p, f_n)
    micro, lost_micro = swing(p.replace(microsteps=16), f_n)
    off = [swing(p, f)[0] for f in (0.5 * f_n, 2.0 * f_n)]
    print(f'vertical Tr8x8 at f_n = {f_n:.1f} full steps/s: rotor swing {full:.3f} full steps '
          f'with full steps ({lost} full steps lost by 0.6 s), {micro:.4f} with 16 microsteps '
          f'({lost_micro} lost); full steps at 0.5 f_n {off[0]:.3f}, at 2 f_n {off[1]:.3f}')
    assert full > 1.3 * max(off)
    assert micro < 0.1 * full
    assert lost_micro == 0
