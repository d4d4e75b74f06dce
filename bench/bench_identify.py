"""
Benchmark ``leadscrew_sim identify``: a 4-parameter fit of 20 s, 1 kHz recordings, and coverage.

Run: .venv/bin/python bench/bench_identify.py [--seconds 20] [--seeds 6] [--profiles P,..]
[--fit default] [--cases PRESET:MODE,.. [--case-seeds K] [--withheld]]

Part 1 (speed): ``simulate`` records tr12x3 with its friction and backlash
moved 20-30 % from the preset (the fit's start), a 17-bit encoder with half a
count of noise and a 1 um scale with 0.5 um of noise, for ``--seconds`` of
simulated time at 1 kHz: in velocity mode a ladder of nut speeds (0.5 .. 10
mm/s, each up and down, with a load opposing the motion at twice the weight)
and in torque mode a triangular torque pulse past breakaway every second,
raising the nut while it is below its start and lowering it otherwise (so it
never reaches an end stop). ``identify`` fits
mu_s, mu_k, stribeck_velocity and backlash of each; the wall time of the whole
command (reading, fitting, bootstrap) and the re-simulations are printed. With
``--fit default`` it fits identify's default set instead (no ``--fit``), of
recordings with the truth of ``test/cli/test_identify_defaults.py`` (viscous
thread friction, bearing and guide friction added).

Part 2 (coverage): the 4 s velocity case of ``test/cli/test_identify.py``
recorded with ``--seeds`` different sensor seeds; for each fitted parameter
the share of the seeds whose 95 % interval holds the true value.

Part 3 (``--profiles sweep,iso230,...``): ``simulate --excite`` recordings of tr12x3
with the test's truth and sensors, fitted the same way; the errors and verdicts.
Part 4 (``--cases anti_backlash:position,...``): the test's cases, any preset and mode, with
``--case-seeds`` sensor seeds (the test's first), and how many intervals hold the truth;
with ``--withheld`` each recording is fitted as a copy without its parameters record.
Part 5 (``--clean-sweep``): the issue's clean sweep (tr12x3, ideal sensors, mu_k 0.12,
mu_s 0.17) fitted for mu_s, mu_k and the Stribeck velocity: wall time, re-simulations,
errors. Part 6 (``--quantised tr12x3,stick_slip``): the ``sweep`` and ``breakaway``
profiles of each preset with the test's friction truth (x1.25, x0.8, x1.3), a 16-bit
encoder with half a count of noise and a 1 um scale with 0.5 um of noise, fitted for
mu_s, mu_k and the Stribeck velocity; ``--case-seeds`` sensor seeds (7, 11, ..);
``--quantised-profiles sweep`` fits only the sweep. Each line ends with the 95 %
half-widths [% of the value].
"""
import argparse
import importlib
from pathlib import Path
import sys
import tempfile
import time

import numpy as np

from leadscrew_sim import cli, LeadScrewModel
from leadscrew_sim.offline.identify.run import fit_recording

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent / 'test'))
sys.path.insert(0, str(HERE.parent / 'test' / 'cli'))
import test_identify as T  # noqa: E402  (the test's cases)
from bag_factory import strip_records  # noqa: E402, I100  (a copy without the record)
import test_identify_defaults as D  # noqa: E402  (the default set's truth)

FIT = 'mu_s,mu_k,stribeck_velocity,backlash'


def _write(path, times, values):
    with open(path, 'w') as fh:
        for t, v in zip(times, values):
            fh.write(f'{float(t)!r},{float(v)!r}\n')


def long_inputs(tmp, mode, seconds, p):
    """Write the inputs of a ``seconds`` long run of ``p`` in ``mode``; return the options."""
    if mode == 'torque':        # a pulse per second, up while below the start, else down
        pos, neg = T._breakaway(p)
        u = np.arange(1000) * 1e-3 / 0.4
        shape = np.where(u < 1, 1 - np.abs(2 * u - 1), 0.0)
        model = LeadScrewModel(p, 1e-3)
        pulses = []
        for _i in range(int(seconds)):
            x = model.output().nut_position
            pulses.append(1.3 * (neg if x <= p.initial_position else pos) * shape)
            model.run(pulses[-1])   # right hand: a negative torque raises the nut
        tq = np.concatenate(pulses)
        _write(tmp / 'torque.csv', np.arange(len(tq)) * 1e-3, tq)
        return ['--torque-csv', str(tmp / 'torque.csv')]
    f0 = 2.0 * T._static_load(p)
    hold = seconds / 10.0 / 2.0 - 0.1          # two ladders of 5 rungs, up and down
    times, vels, t = [], [], 0.0
    for _ladder in range(2):
        for v in T.LADDER:
            for s in (1.0, -1.0):
                times += [t, t + hold]
                vels += [s * v, 0.0]
                t += hold + 0.1
    _write(tmp / 'velocity.csv', times, vels)
    _write(tmp / 'force.csv', times, [-f0 * np.sign(v) for v in vels])
    return ['--velocity-csv', str(tmp / 'velocity.csv'), '--force-csv', str(tmp / 'force.csv')]


def _args(rec, fit=FIT, extra=()):
    main = importlib.import_module('leadscrew_sim.cli.main')
    return main.build_parser().parse_args(['identify', str(rec), '--preset', 'tr12x3'] +
                                          (['--fit', fit] if fit != 'default' else []) +
                                          list(extra))


def speed(seconds, fit=FIT, modes=('velocity', 'torque')):
    """Print the wall time of fits of ``fit`` ('default': identify's set) of long recordings."""
    true, sets = D.truth() if fit == 'default' else T.truth('tr12x3')
    for mode in modes:
        with tempfile.TemporaryDirectory() as d:
            tmp = Path(d)
            rec = tmp / 'run.mcap'
            cli.main(['simulate', '--preset', 'tr12x3', *long_inputs(tmp, mode, seconds, true),
                      '--duration', str(seconds), *sets, '-q', '-o', str(rec)])
            t0 = time.perf_counter()
            out = fit_recording(_args(rec, fit))
            wall = time.perf_counter() - t0
        res, problem = out['res'], out['problem']
        errs = _errors(res, true)
        print(f'{mode:>8} mode, {seconds:g} s at 1 kHz: {wall:.1f} s wall, '
              f'{problem.evaluations} re-simulations; errors: {errs}')


def coverage(seeds):
    """Print the share of seeds whose 95 % intervals hold the truth (4 s velocity case)."""
    hits, lost, n = {}, {}, 0
    for seed in range(seeds):
        T.SENSORS['sensor_seed'] = 100 + seed
        with tempfile.TemporaryDirectory() as d:
            tmp = Path(d)
            opts, duration = T.profile(tmp, 'tr12x3', 'velocity')
            true, sets = T.truth('tr12x3')
            rec = tmp / 'run.mcap'
            cli.main(['simulate', '--preset', 'tr12x3', *map(str, opts), '--duration',
                      str(duration), *sets, '-q', '-o', str(rec)])
            res = fit_recording(_args(rec))['res']
        n += 1
        for name, vd in zip(res.names, res.verdicts):
            t = getattr(true, name)
            hits[name] = hits.get(name, 0) + bool(vd.identified and vd.lower <= t <= vd.upper)
            lost[name] = lost.get(name, 0) + (not vd.identified)
    for name, k in hits.items():
        print(f'{name:>18}: 95 % interval holds the truth in {k} of {n - lost[name]} seeds '
              f'(not identifiable in {lost[name]})')


#: The excite profiles fitted by part 3, with their options (iso230: one cycle).
PROFILES = {'breakaway': [], 'reversals': [], 'sweep': [],
            'iso230': ['--excite-opt', 'cycles=1', '--excite-opt', 'dwell=0.3']}


def _holds(vd, t):
    """Return whether an identified parameter's 95 % interval holds the true value ``t``."""
    return bool(vd.identified and vd.lower <= t <= vd.upper)


def _errors(res, true, digits=2):
    """Return each fitted parameter's error [%] against ``true``, with its verdict."""
    return ', '.join(f'{n} {100 * (v - getattr(true, n)) / getattr(true, n):+.{digits}f} %'
                     f'{"" if vd.identified else " (not identifiable)"}'
                     f'{" (in its interval)" if _holds(vd, getattr(true, n)) else ""}'
                     for n, v, vd in zip(res.names, res.values, res.verdicts))


def _half_width(vd):
    """Return the 95 % half-width [%] of a verdict, 'or wider' where it is a lower bound."""
    return f'{100 * vd.rel:.3g} %' + (' or wider' if 'or wider' in vd.reason else '')


def profiles(names):
    """Print the errors and verdicts of 4-parameter fits of ``simulate --excite`` recordings."""
    true, sets = T.truth('tr12x3')
    for name in names:
        with tempfile.TemporaryDirectory() as d:
            rec = Path(d) / 'run.mcap'
            cli.main(['simulate', '--preset', 'tr12x3', '--excite', name, *PROFILES[name],
                      *sets, '-q', '-o', str(rec)])
            t0 = time.perf_counter()
            out = fit_recording(_args(rec))
            wall = time.perf_counter() - t0
        res = out['res']
        errs = _errors(res, true)
        print(f'{name:>10}: {out["problem"].n} steps, {out["problem"].slow} left out (slow), '
              f'{wall:.1f} s wall; {errs}')


def cases(names, seeds=1, withheld=False):
    """
    Print the errors and verdicts of the test's cases ``preset:mode``, for sensor seeds.

    ``withheld``: fit copies without the parameters record (no sensor seed or model;
    the load force on its topic only), as a ``ros2 bag record`` of the node leaves them.
    """
    for key in names:
        preset, mode = key.split(':')
        true, sets = T.truth(preset)
        held = {}
        for seed in range(seeds):
            T.SENSORS['sensor_seed'] = 7 + 4 * seed         # 7: the test's seed
            true, sets = T.truth(preset)
            with tempfile.TemporaryDirectory() as d:
                tmp = Path(d)
                opts, duration = T.profile(tmp, preset, mode)
                rec = tmp / 'run.mcap'
                over = T.NO_OVERSPEED if mode == 'torque' else ()     # as the test's
                cli.main(['simulate', '--preset', preset, *map(str, opts), '--duration',
                          str(duration), *sets, *over, '-q', '-o', str(rec)])
                if withheld:
                    strip_records(rec, tmp / 'bare.mcap')
                    rec = tmp / 'bare.mcap'
                args = _args(rec, extra=over if withheld else ())
                args.preset = preset
                t0 = time.perf_counter()
                out = fit_recording(args)
                wall = time.perf_counter() - t0
            res = out['res']
            for n, vd in zip(res.names, res.verdicts):
                held[n] = held.get(n, 0) + _holds(vd, getattr(true, n))
            errs = _errors(res, true, digits=4)
            anchoring = out['problem'].anchoring
            restarts = f'restarted at {len(anchoring.rests)} rests, ' if anchoring else ''
            bare = ', withheld' if withheld else ''
            print(f'{key:>24} seed {T.SENSORS["sensor_seed"]}{bare}: {out["problem"].slow} '
                  f'steps left out, {restarts}{wall:.1f} s wall; {errs}', flush=True)
        T.SENSORS['sensor_seed'] = 7
        if seeds > 1:
            print(f'{key:>24}: 95 % intervals holding the truth in {seeds} seeds: ' +
                  ', '.join(f'{n} {k}' for n, k in held.items()))


def clean_sweep():
    """Print the fit of the issue's clean sweep: wall time, re-simulations, errors."""
    sets = dict(mu_k=0.12, mu_s=0.17)
    true = T.load_preset('tr12x3', **sets)
    with tempfile.TemporaryDirectory() as d:
        rec = Path(d) / 'sw3.mcap'
        cli.main(['simulate', '--preset', 'tr12x3', '--excite', 'sweep', '-q', '-o', str(rec)]
                 + [a for n, v in sets.items() for a in ('--set', f'{n}={v}')])
        t0 = time.perf_counter()
        out = fit_recording(_args(rec, 'mu_s,mu_k,stribeck_velocity'))
        wall = time.perf_counter() - t0
    res = out['res']
    errs = ', '.join(f'{n} {100 * (v - getattr(true, n)) / getattr(true, n):+.5f} % '
                     f'({vd.status})' for n, v, vd in zip(res.names, res.values, res.verdicts))
    print(f'clean sweep: {wall:.1f} s wall, {out["problem"].evaluations} re-simulations; '
          f'{errs}')


#: The sensors of part 6: a 16-bit encoder with half a count of noise, a 1 um scale.
QUANTISED = dict(encoder_counts=2 ** 16, encoder_noise=0.5 * 2 * np.pi / 2 ** 16,
                 scale_resolution=1e-6, scale_noise=5e-7)


def quantised(presets, seeds=1, names=('sweep', 'breakaway')):
    """Print the fits of mu_s, mu_k, stribeck_velocity of sweep and breakaway, 16-bit encoder."""
    fit = 'mu_s,mu_k,stribeck_velocity'
    for preset in presets:
        p0 = T.load_preset(preset)
        for name in names:
            for seed in range(seeds):
                values = {n: getattr(p0, n) * T.TRUTH[n] for n in fit.split(',')}
                values.update(QUANTISED, sensor_seed=7 + 4 * seed)
                true = T.load_preset(preset, **values)
                with tempfile.TemporaryDirectory() as d:
                    rec = Path(d) / 'run.mcap'
                    cli.main(['simulate', '--preset', preset, '--excite', name, '-q', '-o',
                              str(rec)] + [a for n, v in values.items()
                                           for a in ('--set', f'{n}={v!r}')])
                    args = _args(rec, fit)
                    args.preset = preset
                    t0 = time.perf_counter()
                    out = fit_recording(args)
                    wall = time.perf_counter() - t0
                print(f'{preset:>10} {name:>9} seed {7 + 4 * seed}: {out["problem"].slow} '
                      f'steps left out, {wall:.1f} s wall; '
                      f'{_errors(out["res"], true, digits=3)}; 95 % half-widths '
                      f'{", ".join(_half_width(vd) for vd in out["res"].verdicts)}',
                      flush=True)


def main():
    """Run the parts asked for (speed, coverage, profiles)."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[1])
    ap.add_argument('--seconds', type=float, default=20.0, help='0: no speed part')
    ap.add_argument('--seeds', type=int, default=6, help='0: no coverage part')
    ap.add_argument('--profiles', default='', help='comma list of excite profiles to fit '
                    f'({", ".join(PROFILES)})')
    ap.add_argument('--cases', default='', help='comma list of preset:mode cases of the '
                    'test to fit (e.g. anti_backlash:position)')
    ap.add_argument('--case-seeds', type=int, default=1, help='sensor seeds of each case '
                    '(7, 11, 15, ...; 7 is the test\'s)')
    ap.add_argument('--fit', default=FIT, help='parameters of the speed part (default '
                    f'{FIT}; default: identify\'s default set, no --fit)')
    ap.add_argument('--modes', default='velocity,torque', help='drive modes of the speed part')
    ap.add_argument('--withheld', action='store_true', help='fit the --cases as copies '
                    'without the parameters record (no sensor seed or model)')
    ap.add_argument('--clean-sweep', action='store_true', help='fit the clean sweep')
    ap.add_argument('--quantised', default='', help='comma list of presets whose sweep and '
                    'breakaway profiles are fitted with a 16-bit encoder')
    ap.add_argument('--quantised-profiles', default='sweep,breakaway',
                    help='the profiles of --quantised')
    a = ap.parse_args()
    if a.seconds:
        speed(a.seconds, a.fit, [m for m in a.modes.split(',') if m])
    if a.seeds:
        coverage(a.seeds)
    if a.profiles:
        profiles([n for n in a.profiles.split(',') if n])
    if a.cases:
        cases([n for n in a.cases.split(',') if n], a.case_seeds, a.withheld)
    if a.clean_sweep:
        clean_sweep()
    if a.quantised:
        quantised([n for n in a.quantised.split(',') if n], a.case_seeds,
                  [n for n in a.quantised_profiles.split(',') if n])
    return 0


if __name__ == '__main__':
    sys.exit(main())
