"""
``leadscrew_sim identify`` without ``--fit``: the default parameter set on one synthetic recording.

The recording is the velocity case of ``test_identify.py`` (tr12x3, a ladder
of nut speeds 0.5 .. 10 mm/s up and down against a force of twice the
payload's weight, so the thread contact changes flank at every reversal; a
17-bit encoder with half a count of noise and a 1 um scale with 0.5 um of
noise), with its mu_s, mu_k, Stribeck velocity and backlash moved x1.25,
x0.8, x1.3, x0.75 from the preset and with viscous thread friction, bearing
and guide friction that the preset does not have (it starts them at 0). Each
true value lies inside its fitting bounds, none on one. The oracle is the
true parameter set.
"""
import importlib
import math

from helpers import cli_ok
from leadscrew_sim import load_preset
from leadscrew_sim.analysis.identify.data import Coordinate, interval_jacobian, judge
from leadscrew_sim.analysis.identify import fit as ident
import numpy as np
import pytest
from test_identify import profile, SENSORS, TOLERANCE, TRUTH

#: The default set the identification is asked for: the thread's Coulomb, Stribeck and
#: viscous friction, the backlash, the bearing's and the guide's Coulomb friction.
ISSUE_SET = ('mu_s', 'mu_k', 'stribeck_velocity', 'mu_viscous', 'backlash',
             'bearing_coulomb', 'guide_coulomb')

#: True values of the terms the preset has at 0: viscous thread friction [s/m] (0.01 more
#: friction coefficient at the top rung's 0.1 m/s of sliding), a bearing torque [N m] of
#: 0.7 % of the breakaway torque, a guide force [N] of 4 % of the payload's weight.
EXTRA = dict(mu_viscous=0.1, bearing_coulomb=0.004, guide_coulomb=4.0)

#: Tolerances (relative, absolute floor) of the terms the issue gives none for. Each term's
#: share of the motor torque bounds how well the torque's noise fixes it: 1e-3 N m of
#: noise, correlated over about 100 steps, averages over the 3000 sliding steps to about
#: 2e-4 N m; the bearing's 4e-3 N m are then known to 5 %, the viscous term's 0.01 of the
#: friction coefficient (about 4e-3 N m at the top rung, less below) to about 10 %, and the
#: guide's 4 N (about 2e-3 N m at the motor) to 10 %, worse where it trades off against the
#: backlash (both decide how far the nut lags through the gap at a reversal): 20 %.
EXTRA_TOLERANCE = dict(mu_viscous=(0.10, 0.0), bearing_coulomb=(0.10, 0.0),
                       guide_coulomb=(0.20, 0.0))


def truth():
    """Return the true ScrewParams of the recording and simulate's ``--set`` options."""
    p = load_preset('tr12x3')
    values = {n: getattr(p, n) * f for n, f in TRUTH.items()}
    values.update(EXTRA, **SENSORS)
    sets = []
    for n, v in values.items():
        sets += ['--set', f'{n}={v!r}']
    return load_preset('tr12x3', **values), sets


@pytest.fixture(scope='module')
def fitted(tmp_path_factory):
    """Return (recording, fit_recording's result) of the default set (made once)."""
    tmp = tmp_path_factory.mktemp('defaults')
    opts, duration = profile(tmp, 'tr12x3', 'velocity')
    _true, sets = truth()
    rec = tmp / 'run.mcap'
    cli_ok('simulate', '--preset', 'tr12x3', *opts, '--duration', duration, *sets, '-q',
           '-o', rec)
    main = importlib.import_module('leadscrew_sim.cli.main')
    from leadscrew_sim.offline.identify.run import fit_recording
    args = main.build_parser().parse_args(['identify', str(rec), '--preset', 'tr12x3'])
    return rec, fit_recording(args)


def test_the_default_set_is_the_issues(fitted):
    """Without --fit, identify fits exactly the issue's seven parameters, in its order."""
    _rec, out = fitted
    assert tuple(out['res'].names) == ISSUE_SET
    start = load_preset('tr12x3')
    true, _sets = truth()
    for name in ISSUE_SET:        # every truth inside its bounds, none on one
        lo, hi = ident.bounds(name, start)
        assert lo < getattr(true, name) < hi, (name, lo, hi)


def test_default_set_recovers_the_true_parameters(fitted):
    """Each default parameter: identified within its tolerance, its interval holds the truth."""
    _rec, out = fitted
    res = out['res']
    true, _sets = truth()
    tolerance = dict(TOLERANCE, **EXTRA_TOLERANCE)
    for name, value, vd in zip(res.names, res.values, res.verdicts):
        t = getattr(true, name)
        rel, floor = tolerance[name]
        assert vd.identified, vd
        assert abs(value - t) <= max(rel * abs(t), floor), (name, value, t)
        # the 95 % interval widened to 99.9 % (x 3.29 / 1.96) as in test_identify: seven
        # 95 % intervals would all hold the truth in only 70 % of the seeds (0.95^7)
        k = 3.29 / 1.96
        assert value - k * (value - vd.lower) <= t <= value + k * (vd.upper - value), \
            (name, t, vd)
    # the fitted set explains the recording to its noise: RMS / sigma of each signal below
    # the 2.5 at which identify rejects a fit (the noise alone gives about 1)
    meas, problem = out['problem'].measurements, out['problem']
    for name, rms in zip(meas.names, meas.rms(out['final'])):
        assert rms / problem.noise[name][0] < 2.5, (name, rms)


def test_report_lists_every_default_parameter(fitted):
    """The report has one row per default parameter with its interval and verdict."""
    rec, out = fitted
    from leadscrew_sim.cli.identify_report import report
    lines = report(str(rec), out).splitlines()
    head = next(i for i, line in enumerate(lines) if line.startswith('parameter '))
    for i, name in enumerate(ISSUE_SET):      # the table's rows, in the set's order
        row = lines[head + 1 + i]
        assert row.startswith(name + ' '), (name, row)
        assert row.rstrip().endswith('  identified') and '[' in row, row


def _at_the_bound(truth_value, seed):
    """Return the verdict of a linear one-parameter fit bounded below by 0, data from ``seed``."""
    from scipy.optimize import least_squares
    rng = np.random.default_rng(seed)
    x = np.linspace(0.0, 1.0, 400)
    y = truth_value * x + rng.normal(0.0, 1.0, x.size)

    def fun(z):
        return (z[0] * x - y)

    c = Coordinate('guide_coulomb', 1.0, 0.0, 100.0, False, 1.0, 1.0)
    r = least_squares(fun, [1.0], bounds=([0.0], [100.0]))
    jac = x[:, None]
    cov = np.linalg.inv(jac.T @ jac)      # white residuals of unit variance
    return judge([c], r.x, jac, cov, r.fun, np.array([0.0]), np.array([100.0]), 0.95,
                 dof=x.size - 1)[0], float(r.x[0])


def test_an_interval_at_a_bound_holds_a_truth_on_it():
    """
    A truth on the lower bound: the interval, clipped to the bound, holds it at 95 % or more.

    Closed form: the unconstrained estimate is normal about the truth 0 with
    standard error 1 / sqrt(sum x^2); the fit clips it to 0 in half of the
    seeds, where the interval [0, 1.96 s.e.] holds 0 by construction, and in the
    other half the interval [v - 1.96 s.e., v + 1.96 s.e.] misses 0 only when
    v > 1.96 s.e. (2.5 % of all seeds). Over 200 seeds the share holding 0 is
    97.5 % with a binomial standard deviation of 1.1 %: the test asks >= 93 %
    (4 standard deviations below).
    """
    held, at_bound = 0, 0
    for seed in range(200):
        vd, v = _at_the_bound(0.0, seed)
        held += vd.lower <= 0.0 <= vd.upper
        if 'at its lower bound' in vd.reason:      # the optimiser stops within 1e-9 of it
            at_bound += 1
            assert v < 1e-9 and vd.lower == 0.0 and vd.upper > 0.0, (v, vd)
    assert held >= 186, held
    assert 70 <= at_bound <= 130, at_bound   # half of 200, +-4 binomial sd (7.1)
    from scipy.stats import t as student
    se = 1.0 / math.sqrt(np.sum(np.linspace(0.0, 1.0, 400) ** 2))
    tq = float(student.ppf(0.975, 399))
    vd, v = _at_the_bound(0.0, 0)
    assert v < 1e-9                        # seed 0's estimate is on the bound
    # one-sided: [0, v + t s.e.], the part of v +- t s.e. within the bounds (t of 399
    # degrees of freedom, 1.966)
    assert vd.lower == 0.0 and abs(vd.upper - tq * se) <= 1e-6 * se, (vd, se)


def test_the_jacobian_of_a_value_at_its_bound_is_its_slope():
    """
    A fit on its lower bound: the intervals' Jacobian is the slope inside, not 0.

    The residuals see the parameter through its value, clipped into the
    bounds (as the fit's), so a backward difference from the bound changes
    nothing: were it taken, the flattest of the differences would be 0 and
    the parameter "without sensitivity". Oracle: the residuals are linear,
    z x - y, so every difference inside the bounds is x to round-off.
    """
    c = Coordinate('guide_coulomb', 1.0, 0.0, 100.0, False, 1.0, 1.0)
    x = np.linspace(0.0, 1.0, 50)

    def fun(z):
        """Return the residuals of the clipped value z x (data 0)."""
        return c.to_value(z[0]) * x

    z = np.array([1e-12])                      # where the optimiser stops on the bound
    jac = interval_jacobian(fun, z, fun(z), (1e-5, 1e-3), np.array([0.0]), np.array([100.0]))
    assert np.allclose(jac[:, 0], x, rtol=1e-6, atol=1e-9), jac[:5, 0]
    vd = judge([c], z, jac, np.linalg.inv(jac.T @ jac), fun(z), np.array([0.0]),
               np.array([100.0]), 0.95, dof=49)[0]
    assert 'no sensitivity' not in vd.reason and 'at its lower bound' in vd.reason, vd
