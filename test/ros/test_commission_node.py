"""
End to end over DDS: ``excite commission`` drives the node, ``commission`` calibrates from it.

The node runs as a real process with friction chosen here (not the preset's)
and records; ``excite commission`` publishes to it from a second process and
writes the segments sidecar (the node's recording has no segments record).
``commission`` on that file recovers the friction. The node restarted with
the fit.yaml it wrote then runs a new move (reversals of another amplitude);
the oracle of what the axis would have done is that move's commands
re-simulated with the truth: the restarted node's nut stays within twice
the larger of the held-out error the report stated of that kind of move
and the spread the reported intervals give that move.
"""
import json
from pathlib import Path
import signal
import subprocess
import sys
import time

from helpers import cli_ok
import numpy as np
import pytest
import yaml

#: The axis's friction, away from the preset's (mu_s 0.2, mu_k 0.15, v_s 1 mm/s).
TRUTH = dict(mu_s=0.23, mu_k=0.13, stribeck_velocity=1.2e-3)
#: The axis's sensors (as test_excite_node's identify): a 17-bit encoder and a 1 um scale.
SENSORS = ('encoder_counts:=131072', 'scale_resolution:=1.0e-6')
#: The identify tolerances (relative).
TOLERANCE = dict(mu_s=0.02, mu_k=0.01, stribeck_velocity=0.10)
#: Wait between the exciter's exit and the node's stop [s] (as test_excite_node).
DRAIN_S = 1.0


def _node(run_exe, directory, *params):
    """Start the node stepped at real time (the file re-simulates exactly), recording."""
    args = ['--ros-args', '-p', f'record_dir:={directory}', '-p', 'record_prefix:=cm',
            '-p', 'clock_mode:=stepped', '-p', 'real_time_factor:=1.0',
            '-p', 'command_timeout:=2.0']
    for p in params:
        args += ['-p', p]
    return run_exe('leadscrew_sim.node', *args)


def _excite(*args, timeout=120):
    r = subprocess.run([sys.executable, '-m', 'leadscrew_sim.cli', 'excite', *map(str, args),
                        '--wait-timeout', '60', '-q'], capture_output=True, text=True,
                       timeout=timeout)
    assert r.returncode == 0 and 'Traceback' not in r.stderr, r.stdout + r.stderr
    return r


def _one(directory):
    files = sorted(Path(directory).glob('cm_*.mcap'))
    assert len(files) == 1, files
    return files[0]


@pytest.mark.timeout(800)
def test_commission_over_dds_recovers_the_axis_and_the_restart_reproduces_it(run_exe,
                                                                             tmp_path):
    first, second = tmp_path / 'first', tmp_path / 'second'
    first.mkdir()
    second.mkdir()
    node = _node(run_exe, first, 'preset:=tr12x3', *SENSORS,
                 *(f'{n}:={v!r}' for n, v in TRUTH.items()))
    sidecar = tmp_path / 'run.segments.json'
    _excite('commission', '--segments', sidecar)
    time.sleep(DRAIN_S)
    assert node.stop(signal.SIGINT, timeout=30) == 0, node.output()
    rec = _one(first)
    out = tmp_path / 'out'
    # about 30 s; up to 200 s on a quiet host when the fit needs its last attempt (a run
    # whose sweep began 1.2 s in: every attempt up to the loop's response measured over
    # the steps compared stopped in a wrong minimum)
    cli_ok('commission', rec, '-o', out, '--segments', sidecar, '-q', timeout=600)
    report = json.loads((out / 'report.json').read_text())
    assert report['sections']['axis']['segments_source'].startswith('the sidecar')
    parts = list(report['sections']['axis']['segments'])
    assert parts == ['sweep', 'breakaway', 'reversals', 'chirp']
    fitted = yaml.safe_load((out / 'fit.yaml').read_text())['/**']['ros__parameters']
    rows = {row['name']: row for row in report['sections']['identify']['parameters']}
    lost = [n for n in ('mu_s', 'mu_k') if rows[n]['verdict'] == 'not identified']
    if lost:
        # the fit could not determine the friction on this run's recording: a known limit
        # (the cost over this sweep is rough, and on some DDS timings the fit, or the
        # bootstrap's refits, stop in other minima of the valley of mu_s and the Stribeck
        # velocity; doc/commissioning.md). It must be said so, with nothing written as a
        # number, never a wrong value with a narrow interval; the run then cannot show the
        # recovery this test names, which pytest reports as an expected failure
        for n in lost:
            assert rows[n]['reason'] and n not in fitted, rows[n]
        pytest.xfail(f'{", ".join(lost)} not identified on this recording: '
                     + '; '.join(rows[n]['reason'] for n in lost))
    for name, tol in TOLERANCE.items():
        row = rows[name]
        if name == 'stribeck_velocity' and row['verdict'] == 'not identified':
            # its cost valley with mu_s is long (correlation 0.999): on some DDS timings the
            # bootstrap's refits spread it beyond the verdict's limit; then it is said so and
            # left out of fit.yaml (the node keeps the preset's), never written as a number
            assert row['reason'] and name not in fitted, row
            continue
        assert name in fitted, report['sections']['identify']
        if 'stribeck_velocity' not in fitted:
            # with the Stribeck velocity not determined, the others are fitted with it held at
            # the preset's (17 % below the truth): the report says they are conditional on it
            # and widens their intervals to cover its plausible range, which must then hold
            # the truth; the value itself moves with the held one (a run of 2026-12-04: mu_s
            # 0.2221, 3.4 % off, interval +-46 %), so the tolerance is not asked of it
            assert 'conditional on stribeck_velocity held' in row['reason'], row
            assert row['lower'] <= TRUTH[name] <= row['upper'], row
            continue
        if 0.5 * (row['upper'] - row['lower']) > tol * row['value']:
            # the report says the value is known less well than the tolerance (a run of
            # 2026-12-07: the Stribeck velocity 0.99 mm/s +-41 %): its interval, not the
            # tolerance, is then what it claims, and it must hold the truth
            assert row['lower'] <= TRUTH[name] <= row['upper'], row
            continue
        # (whether the 95 % intervals hold the truth is the simulated tests' question: there
        # the recording is fixed by its seed, here each run's DDS timing makes a new one, and
        # a 95 % interval misses in one run of twenty by design)
        assert abs(fitted[name] - TRUTH[name]) <= tol * TRUTH[name], (name, fitted[name])
    stated = report['sections']['twin']['held_out']['rms_um'] * 1e-6

    # The node restarted with fit.yaml runs a new move.
    node = run_exe('leadscrew_sim.node', '--ros-args', '--params-file', str(out / 'fit.yaml'),
                   '-p', f'record_dir:={second}', '-p', 'record_prefix:=cm',
                   '-p', 'clock_mode:=stepped', '-p', 'real_time_factor:=1.0',
                   '-p', 'command_timeout:=2.0', *(a for p in SENSORS for a in ('-p', p)))
    # a new run of the kind of move the report's held-out figure judged (the reversals part,
    # its default levels): the stated RMS is a figure of that move, not of any move
    _excite('reversals')
    time.sleep(DRAIN_S)
    assert node.stop(signal.SIGINT, timeout=30) == 0, node.output()
    moved = _one(second)
    from leadscrew_sim.offline.options import open_recording
    from leadscrew_sim.offline.replay.resim import Resim
    r = open_recording(moved)
    twin = Resim(r)                          # the node's own (calibrated) parameters
    assert twin.params.mu_s == fitted['mu_s']
    axis = Resim(r, TRUTH)                   # the axis: the same commands, the truth
    x_twin, x_axis = twin.replay()['nut_position'], axis.replay()['nut_position']
    # from the first 0.5 s on, as the report compares (the move starts at rest)
    k0 = int(0.5 / (twin.dt_ns / 1e9))
    e = x_twin[k0:] - x_axis[k0:]
    from leadscrew_sim.analysis.excitation.profiles import make_profile
    amplitude = make_profile('reversals', twin.params).options['amplitude']
    assert np.ptp(x_axis) > 1.9 * amplitude  # it moved: to both sides by the amplitude
    # The report's held-out figure is one run of this move (entered from the breakaway's end
    # state, its own DDS timing); a new run from rest samples the same model error again. Its
    # RMS stays within twice the stated figure (0.1 um added for a fit of exact data): runs
    # of this test gave 0.24, 1.4 and 1.7 times the stated figure, most of it a drift that
    # the friction's error leaves at the dwells. That figure is one sample, and a fit within
    # its intervals can miss a new move by more: a run of 2026-12-07 (mu_s 0.05 % off, the
    # Stribeck velocity 1.2 %) stated 0.75 um and missed this move by 1.94 um, while the
    # twin moved to its intervals' ends (mu_s +-1 %, the Stribeck velocity +-22 %) moved it
    # by up to 5.9 um. The bound is twice the larger of the stated figure and that spread:
    # the node reproduces the axis as well as the report says it can be known.
    rms = float(np.sqrt(np.mean(e * e)))
    spread = 0.0
    for name in TOLERANCE:
        row = rows[name]
        if name not in fitted:
            continue
        for end in (row['lower'], row['upper']):
            d = Resim(r, {name: end}).replay()['nut_position'][k0:] - x_twin[k0:]
            spread = max(spread, float(np.sqrt(np.mean(d * d))))
    print(f'new move: {rms * 1e6:.3g} um RMS; stated {stated * 1e6:.3g} um; the intervals '
          f'move it by up to {spread * 1e6:.3g} um')
    assert rms <= 2.0 * max(stated, spread) + 1e-7, (rms, stated, spread)
