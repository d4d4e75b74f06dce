"""
A reset model is a new model, and the lean run returns the arrays of the full one.

The stability map reuses one model per parameter set (reset between runs)
and reads two arrays of each run through ``run(values=...)``: both must give
the bytes of a new model's full run.
"""
import math

import numpy as np
import pytest

from leadscrew_sim.core.drive_modes import MODE_VELOCITY
from leadscrew_sim.core.model import LeadScrewModel
from leadscrew_sim.core.output import REPORTED
from leadscrew_sim.core.presets import load_preset


def rows(model, n, w):
    """Return n velocity command rows at w [rad/s]."""
    return np.tile([[MODE_VELOCITY, math.nan, w, 0.0]], (n, 1))


@pytest.mark.parametrize('preset', ['stick_slip', 'tr12x3', 'anti_backlash', 'nema17_tr8x8'])
def test_reset_model_runs_as_a_new_one(preset):
    """Run, reset, run again: the second run has the bytes of a new model's run."""
    p = load_preset(preset)
    new = LeadScrewModel(p).run(None, commands=rows(LeadScrewModel(p), 800, 30.0))
    m = LeadScrewModel(p)
    m.run(None, commands=rows(m, 500, -20.0))      # stick, slip, reverse: scratch is used
    m.reset()
    again = m.run(None, commands=rows(m, 800, 30.0))
    for k in new:
        assert np.asarray(new[k]).tobytes() == np.asarray(again[k]).tobytes(), k


def test_lean_run_returns_the_full_runs_arrays():
    """run(values=...) returns exactly the named arrays of the full run, and nothing else."""
    p = load_preset('stick_slip')
    names = ('nut_velocity', 'stuck', 'motor_torque', 'contact', 'following_error')
    full = LeadScrewModel(p).run(None, commands=rows(LeadScrewModel(p), 600, 25.0))
    lean = LeadScrewModel(p).run(None, commands=rows(LeadScrewModel(p), 600, 25.0),
                                 values=names)
    assert set(lean) == set(names)
    for k in names:
        assert lean[k].dtype == full[k].dtype, k
        assert lean[k].tobytes() == full[k].tobytes(), k


def test_lean_run_refuses_an_unknown_name():
    """An unknown value name: one ValueError naming it and the allowed names; nothing runs."""
    m = LeadScrewModel(load_preset('stick_slip'))
    before = m.state.copy()
    with pytest.raises(ValueError, match="'nut_speed'") as info:
        m.run(None, commands=rows(m, 10, 1.0), values=('nut_velocity', 'nut_speed'))
    assert all(name in str(info.value) for name in REPORTED)   # the allowed names listed
    assert m.state.tobytes() == before.tobytes()
