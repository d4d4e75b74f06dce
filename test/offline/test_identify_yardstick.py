"""
The yardstick of ``identify`` on a real axis's recording: at the truth, its misfit is the noise.

A user's bag carries no sensor seed and no parameter record: the noise the
drive reacted to is unknown, and so is the command-to-state delay. Each bag
here is written with rosbags (an independent writer) from a ``simulate`` run
with secret friction values, a 16-bit motor encoder with Gaussian noise and
a 1 um linear scale with noise, in ros2_control's layout: forward-controller
commands (Float64MultiArray) at 100 Hz logged 0.4 ms after they act, and
joint states at irregular 2-10 ms stamps with drops (or every 1 ms state).

The oracle is the noise model itself: the residual of the true parameters
is the sensor noise plus the drive loop's response to it, so identify's
RMS / sigma at the truth is about 1 on each fitted signal. 1.5 is the bar of
the issue: with ~640 states the RMS of Gaussian residuals is within 3 % of
sigma, and the loop's share of sigma is measured with one other seed (its
spread is heavy-tailed, a factor 2 between seeds), so a correct comparison
stays below it while a lag of one command delay (0.4 ms at 21 rad/s:
8e-3 rad, 40 sigma) or a twin that drifts from the recording does not.
Before the delay was fitted with the parameters, the velocity bag gave
RMS / sigma 18.7 on the screw angle at the truth.
"""
import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
import bag_factory as B  # noqa: E402

#: The sensors of the axis: counts [-], noise [rad], resolution [m], noise [m].
SENSORS = dict(encoder_counts=65536, encoder_noise=2e-4, scale_resolution=1e-6,
               scale_noise=3e-7)
#: The secret friction of the axis [-].
SECRET = dict(mu_s=0.23, mu_k=0.17)
DURATION = 4.0
KINDS = {'velocity': ('--velocity-csv', '/forward_velocity_controller/commands', 1),
         'position': ('--position-csv', '/forward_position_controller/commands', 1),
         'torque': ('--torque-csv', '/forward_effort_controller/commands', 0)}


def _command(kind, t):
    """Return the commanded profile of ``kind`` at times ``t`` [s] (m/s, m or N m)."""
    if kind == 'velocity':
        v = np.where((t > 0.3) & (t < 1.3), 0.01, np.where((t > 1.8) & (t < 2.6), -0.012, 0.0))
        return v * (1 + 0.3 * np.sin(2 * np.pi * 1.5 * t))
    if kind == 'position':
        x = np.zeros_like(t)
        for t0, t1, a, b in ((0.3, 1.3, 0.0, 0.01), (1.8, 2.8, 0.01, 0.002)):
            s = np.clip((t - t0) / (t1 - t0), 0, 1)
            x = np.where(t >= t0, a + (b - a) * (3 * s ** 2 - 2 * s ** 3), x)
        return x
    return np.where((t > 0.3) & (t < 1.0), 0.35, np.where((t > 1.8) & (t < 2.5), -0.3, 0.0))


def _bag(tmp, kind, seed, every_ms):
    """Write the bag of ``kind``: sensor seed ``seed``, states every 2-10 ms or every 1 ms."""
    flag, topic, index = KINDS[kind]
    t = np.arange(0.0, DURATION, 0.01)
    col = _command(kind, t)
    csv = tmp / f'{kind}.csv'
    csv.write_text(''.join(f'{a:.6f},{float(b)!r}\n' for a, b in zip(t, col)))
    out = tmp / f'{kind}.mcap'
    from helpers import cli_ok
    args = ['simulate', '--preset', 'tr12x3', '--duration', DURATION, flag, csv, '-o', out, '-q']
    for k, v in {**SENSORS, **SECRET, 'sensor_seed': seed}.items():
        args += ['--set', f'{k}={v}']
    cli_ok(*args)
    stamps, pos, vel, eff = B.sim_states(out)
    keep = B.irregular(len(stamps), seed) if every_ms is None else \
        np.arange(1, len(stamps))
    msgs = B.state_messages(stamps, pos, vel, eff, keep)
    for a, b in zip(t, col):
        vals = [0.0, 0.0]
        vals[index] = b
        msgs.append((B.EPOCH + int(round(a * B.NS)) + B.LATENCY, topic,
                     'std_msgs/msg/Float64MultiArray', B.multi_array(vals)))
    return B.write_bag(tmp / f'{kind}_{seed}_bag', msgs), topic, index


def _misfit_at_truth(bag, topic, index):
    """Return {signal: RMS / sigma} of identify's residuals with the true parameters."""
    from leadscrew_sim.cli.main import build_parser
    from leadscrew_sim.offline.identify.inputs import start_params
    from leadscrew_sim.offline.identify.problem import Problem
    from leadscrew_sim.offline.options import open_recording
    sets = [a for k, v in SECRET.items() for a in ('--set', f'{k}={v}')]
    args = build_parser().parse_args([
        'identify', str(bag), '--preset', 'tr12x3', *sets, '--state-topic', B.STATES,
        '--screw-joint', B.SCREW, '--nut-joint', B.NUT, '--command-topic', topic,
        '--command-index', str(index)])
    rec = open_recording(args.file)
    start, _label = start_params(args, rec)
    problem = Problem(args, rec, start)
    r = problem.residuals({})
    meas = problem.measurements
    out = {}
    for i, name in enumerate(meas.names):
        used = meas.mask[i]
        out[name] = float(np.sqrt(np.mean(r[i][used] ** 2)))
    return out, problem


@pytest.mark.parametrize('kind,seed,every_ms', [
    ('velocity', 5, None), ('position', 5, None), ('torque', 5, None),
    ('velocity', 8, 1), ('position', 8, 1)])
def test_at_the_truth_the_misfit_is_the_noise(tmp_path, kind, seed, every_ms):
    """Seed and parameter record withheld, noise unknown: RMS / sigma <= 1.5 per signal."""
    bag, topic, index = _bag(tmp_path, kind, seed, every_ms)
    misfit, problem = _misfit_at_truth(bag, topic, index)
    assert set(misfit) >= {'screw_angle', 'nut_position'}, misfit
    assert all(v <= 1.5 for v in misfit.values()), (kind, misfit, problem.noise)
    # the delay fitted with the parameters is the latency the bag was written with (the
    # states lag the commands' log times by -0.4 ms): within a tenth of a 1 ms step
    if kind != 'torque':
        assert abs(problem.delay + B.LATENCY / B.NS) < 1e-4, problem.delay
    # the noise levels are the data's: the starting set declares no sensor noise
    assert all('estimated from the data' in how for _s, how in problem.noise.values()), \
        problem.noise
