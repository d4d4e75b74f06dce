"""
``identify`` on test_identify's cases as a ``ros2 bag record`` of the node leaves them.

The recordings are test_identify's: chosen friction and backlash, a 17-bit
encoder and a 1 um scale with noise, and in velocity and position mode a
load force against each move. Each is copied by the mcap library's writer
without its parameters record: no sensor seed, no sensor model, and the load
force only on the node's ``external_force`` topic. ``identify`` reads the
copy as a foreign recording, with no mapping flags. The oracle is the true
parameter set the run was made with: mu_s and mu_k must be identified, and
every identified parameter's 95 % interval, widened to 99.9 % as in
test_recovers_the_true_parameters, must hold its true value. The values are
not held to that test's tolerances: without the seed the fit compares with
another draw of the loop's noise, and its intervals say how far it can be.
"""
import importlib
import re

from bag_factory import strip_records
import pytest
from test_identify import FIT, recording, truth

#: The cases that fit with their seed and record withheld. stick_slip's position ladder
#: is the one test_identify gets wrong with its seed (a wrong basin); tr12x3's and the
#: split nut's position ladders and stick_slip's torque pulses are rejected, the fit
#: not explaining them (doc/identification.md, "Recordings of the node's own topics").
BARE = [('stick_slip', 'position'), ('anti_backlash', 'velocity'), ('stick_slip', 'velocity')]


@pytest.mark.parametrize('preset,mode', BARE)
def test_a_bare_recording_against_its_load_force(tmp_path_factory, preset, mode):
    """Stripped of its record, the run's load force acts from its topic; the intervals hold."""
    rec = recording(tmp_path_factory, preset, mode)
    bare = tmp_path_factory.mktemp('bare') / 'bare.mcap'
    strip_records(rec, bare)
    main = importlib.import_module('leadscrew_sim.cli.main')
    from leadscrew_sim.offline.identify.run import fit_recording
    from leadscrew_sim.cli.identify_report import report
    out = fit_recording(main.build_parser().parse_args(
        ['identify', str(bare), '--preset', preset, '--fit', FIT]))
    assert out['problem'].foreign
    text = report('bare.mcap', out)
    taken = re.search(r'external force from /external_force \((\d+) taken\)', text)
    assert taken and int(taken.group(1)) > 0, text
    true, _sets = truth(preset)
    res = out['res']
    k = 3.29 / 1.96                  # 99.9 %, as in test_recovers_the_true_parameters
    for name, value, vd in zip(res.names, res.values, res.verdicts):
        if name in ('mu_s', 'mu_k'):
            assert vd.identified, (name, vd)
        if vd.identified:
            t = getattr(true, name)
            assert value - k * (value - vd.lower) <= t <= value + k * (vd.upper - value), \
                (name, t, vd)
