"""
The last attempt of identify: fits from the start shifted 10 % up, then down.

A sweep of tr12x3 recorded with friction chosen here (the truth, the
oracle) and the noisy encoder and scale of bench_commission. The
attempt is run on its own, as fit_recording runs it after two fits that
did not explain the recording: its first shifted start must explain it
and land on the truth, the start it reports must stay the plan's, and its
re-simulations must add to those of the fits before it.
"""
import importlib

from helpers import cli_ok
import pytest

TRUTH = dict(mu_s=0.23, mu_k=0.13, stribeck_velocity=1.2e-3)
#: The identify tolerances (relative), as test_commission's.
TOLERANCE = dict(mu_s=0.02, mu_k=0.01, stribeck_velocity=0.10)
SENSORS = dict(encoder_counts=65536, encoder_noise=4.79e-5, scale_resolution=1e-6,
               scale_noise=5e-7, sensor_seed=11)


def test_a_shifted_start_replaces_a_fit_that_missed(tmp_path):
    rec = tmp_path / 'sweep.mcap'
    sets = [a for k, v in {**TRUTH, **SENSORS}.items() for a in ('--set', f'{k}={v}')]
    cli_ok('simulate', '--preset', 'tr12x3', '--excite', 'sweep', *sets, '-o', rec, '-q')
    main = importlib.import_module('leadscrew_sim.cli.main')
    run = importlib.import_module('leadscrew_sim.offline.identify.run')
    from leadscrew_sim.analysis.identify import fit as ident
    from leadscrew_sim.offline.identify.inputs import start_params
    from leadscrew_sim.offline.identify.problem import Problem
    from leadscrew_sim.offline.options import open_recording
    args = main.build_parser().parse_args(
        ['identify', str(rec), '--preset', 'tr12x3', '--fit', ','.join(TRUTH)])
    r = open_recording(rec)
    start, _label = start_params(args, r)
    problem = Problem(args, r, start)
    coords = ident.coordinates(list(TRUTH), start)
    problem.resolve_floor(coords)
    plan = run.Plan(problem, list(TRUTH), start, coords, args.max_nfev)
    weights = dict(problem.measurements.sigma)
    missed = run._fit(plan)
    missed[0].nfev = 1000           # as if two attempts had spent them
    missed = (missed[0], missed[1], missed[2], 'the fit does not explain the recording')
    (res, _initial, _final, misfit), (tries, explained) = run._shifted(plan, weights, missed)
    assert (tries, explained, misfit) == (1, True, '')
    assert res.initial == [getattr(start, n) for n in TRUTH]     # the plan's start, reported
    assert res.nfev > 1000
    for name, value in zip(res.names, res.values):
        assert value == pytest.approx(TRUTH[name], rel=TOLERANCE[name]), (name, value)
