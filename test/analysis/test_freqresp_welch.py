"""
The Welch estimate of a frequency response (analysis/freqresp/welch.py) against known systems.

The oracles are systems the tests build and python-control evaluates: a
lightly damped resonance discretised with the input held over each step
(control.c2d, zero-order hold), driven by seeded white noise with white
measurement noise on the output (control.forced_response); the exact
discrete FRF C (z I - Phi)^-1 Gamma and the coherence of additive output
noise, |H|^2 S_uu / (|H|^2 S_uu + S_nn), are closed forms. The tolerances
are the estimator's own random errors (Bendat & Piersol, Random Data, 4th
ed., table 9.6) with a stated margin.
"""
import math

import control
from leadscrew_sim.analysis.freqresp import welch as W
import numpy as np
import pytest

DT = 1e-3                   # step [s]
SEGMENTS = 8


def resonance(f_n=30.0, zeta=0.1):
    """Return the ZOH discretisation of w^2 / (s^2 + 2 zeta w s + w^2) at DT."""
    w = 2 * math.pi * f_n
    return control.c2d(control.tf([w * w], [1.0, 2 * zeta * w, w * w]), DT, method='zoh')


def exact(sysd, f):
    """Return C (z I - Phi)^-1 Gamma at z = exp(j 2 pi f DT) (python-control)."""
    return np.asarray(sysd(np.exp(2j * math.pi * np.asarray(f) * DT)), dtype=complex)


def paired(sysd, f):
    """Return z C (z I - Phi)^-1 Gamma: the input held over the step ending at y's stamp."""
    return np.exp(2j * math.pi * np.asarray(f) * DT) * exact(sysd, f)


def noisy_run(sysd, n=2 ** 16, sigma_u=1.0, sigma_n=0.05, seed=3):
    """Return (u, y): white input and the output plus white measurement noise."""
    rng = np.random.default_rng(seed)
    u = sigma_u * rng.standard_normal(n)
    y = control.forced_response(sysd, T=np.arange(n) * DT, U=u).outputs
    return u, y + sigma_n * rng.standard_normal(n)


def test_h1_and_coherence_of_a_noisy_resonance_match_the_closed_forms():
    sysd = resonance()
    sigma_u, sigma_n = 1.0, 0.05
    u, y = noisy_run(sysd, sigma_u=sigma_u, sigma_n=sigma_n)
    f, h, coh = W.h1(u, y, DT, SEGMENTS)
    band = (f > 1.0) & (f < 300.0)
    f, h, coh = f[band], h[band], coh[band]
    true = exact(sysd, f)
    # Coherence of additive white output noise with a white input (both flat spectra).
    g2 = np.abs(true) ** 2 * sigma_u ** 2 / (np.abs(true) ** 2 * sigma_u ** 2 + sigma_n ** 2)
    # Random errors with n_d averages (half-overlapped Hann segments: about
    # SEGMENTS independent ones, Welch 1967): |H| and phase sqrt(1 - g2) /
    # (|g| sqrt(2 n_d)); the coherence sqrt(2) g2 (1 - g2) / sqrt(n_d). Every
    # bin within 5 of them (a seeded run: about 2500 bins, 5 sigma is exceeded
    # by one in 10^6), plus 1 % for the resolution bias at the resonance; the
    # coherence also has its bias (1 - g2)^2 / n_d.
    n_d = SEGMENTS
    eps = np.sqrt(1.0 - g2) / (np.sqrt(g2) * np.sqrt(2 * n_d))
    ratio = h / true
    assert np.all(np.abs(np.abs(ratio) - 1.0) <= 5 * eps + 0.01)
    assert np.all(np.abs(np.angle(ratio)) <= 5 * eps + 0.01)
    assert np.all(np.abs(coh - g2) <= 5 * np.sqrt(2 * g2) * (1 - g2) / np.sqrt(n_d) +
                  (1 - g2) ** 2 / n_d + 0.01)
    # The estimate sees the noise: coherence well below 1 where |H| is small.
    assert coh[f > 250].max() < 0.9 and coh[np.abs(f - 30) < 3].min() > 0.99


def test_the_estimate_fails_against_a_wrong_system():
    # The same comparison against a resonance 3 % higher fails: the check can fail
    # (there the tolerance above is below 0.07: coherence > 0.997).
    u, y = noisy_run(resonance())
    f, h, _coh = W.h1(u, y, DT, SEGMENTS)
    band = (f > 20.0) & (f < 40.0)
    wrong = exact(resonance(f_n=30.9), f[band])
    assert np.max(np.abs(np.abs(h[band] / wrong) - 1.0)) > 0.1


def velocity_plant():
    """Return a damped inertia 1 / (J s + b) (torque to velocity), ZOH at DT."""
    return control.c2d(control.tf([1.0], [2e-5, 2e-3]), DT, method='zoh')


def recorded(sysd, n, seed=5):
    """
    Return a recording-like run: commands logged between ticks, states stamped on ticks.

    Times are integer ns. The command acting over step k (from t_k) is the last
    one logged at or before t_k; the state stamped t_k is the output there
    (python-control: y_k = C x_k); the effort stamped t_(k+1) is the torque
    held over step k.
    """
    rng = np.random.default_rng(seed)
    step = 1_000_000
    t0 = 7 * step
    grid = t0 + step * np.arange(n)
    log = np.sort(np.append(t0 - step // 2, t0 + rng.integers(0, n * step, n // 2)))
    cmd = rng.standard_normal(len(log))
    held = np.array([cmd[np.searchsorted(log, t, side='right') - 1] for t in grid])
    x = control.forced_response(sysd, T=np.arange(n) * DT, U=held).outputs
    return t0, step, (log, cmd), (grid, x), (grid + step, held)


def test_alignment_gives_the_zoh_discretisation_and_the_effort_moves_one_step():
    # Commands and efforts both pair the torque held over the step ending at
    # the state's stamp with that state: z C (z I - Phi)^-1 Gamma.
    sysd = velocity_plant()
    n = 2 ** 15
    t0, step, commands, states, efforts = recorded(sysd, n)
    for series, effort in ((commands, False), (efforts, True)):
        u, y = W.align(t0, step, n, series, states, effort=effort)
        assert np.isnan(u[0])          # no command before t0 - dt, no effort stamped t0
        assert np.isfinite(u[1:]).all() and np.isfinite(y).all()
        r = W.welch_response(u[1:], y[1:], DT, 'torque', 'motor_velocity', fmin=2.0,
                             fmax=400.0)
        true = paired(sysd, r.frequency)
        # Noise-free: only the windows' leakage of the plant's 10 ms transient
        # across segment edges (segments of 4096 steps): well below 1 %.
        assert np.max(np.abs(r.response / true - 1.0)) < 0.01
        assert r.coherence.min() > 0.99
    # Taking the effort as a command pairs each state with the effort of the
    # step before: the phase leads by w T, 36 deg at 100 Hz, far outside the
    # tolerance above.
    u, y = W.align(t0, step, n, efforts, states, effort=False)
    r = W.welch_response(u[2:], y[2:], DT, 'torque', 'motor_velocity', fmin=90.0, fmax=110.0)
    shift = np.degrees(np.angle(r.response / paired(sysd, r.frequency)))
    assert shift == pytest.approx(360 * r.frequency * DT, abs=0.5)


def test_a_multisine_keeps_only_its_lines():
    # Lines on the segment grid (period = one segment of 4096 steps): the bins
    # between them carry no input power and are left out.
    n, nper = 2 ** 15, 2 ** 12
    period = nper * DT
    k = np.array([3, 7, 20, 55, 150, 400])
    t = np.arange(n) * DT
    u = sum(np.cos(2 * math.pi * kk / period * t + 0.3 * kk) for kk in k)
    sysd = velocity_plant()
    y = control.forced_response(sysd, T=t, U=u).outputs
    r = W.welch_response(u, y, DT, 'torque', 'motor_velocity', segments=n // nper)
    assert np.allclose(r.frequency, k / period)
    assert np.max(np.abs(r.response / exact(sysd, r.frequency) - 1.0)) < 0.01


def test_too_short_segments_are_refused():
    with pytest.raises(ValueError, match='segments: 8 segments of 40 samples'):
        W.h1(np.ones(40), np.ones(40), DT, 8)
