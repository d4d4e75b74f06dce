"""
A bag read once serves every re-simulation: the same columns as a replay read afresh.

``commission`` re-simulates a robot's bag with the calibrated values several
times (the twin, the spread of its noise, the backlash stage); each reuses
the bag as read (``ForeignReplay.with_params``) and the drive commands of
the replays that map them alike. The oracle is a replay that reads the bag
again and builds its commands from scratch: every column must be the same
to the last bit, for other friction and sensors (the commands shared) and
for commands lost at a drop rate (the commands rebuilt). The bag is the yardstick
test's, written with rosbags: velocity commands at 100 Hz, irregular states.
"""
import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import test_identify_yardstick as Y  # noqa: E402  (its bag)
import bag_factory as B  # noqa: E402


def _mapping(topic, index):
    return argparse.Namespace(state_topic=B.STATES, screw_joint=B.SCREW, nut_joint=B.NUT,
                              command_topic=[topic], command_index=index)


def _same(a, b):
    assert set(a) == set(b)
    for k in a:
        x, y = np.ascontiguousarray(a[k]), np.ascontiguousarray(b[k])
        assert x.dtype == y.dtype and x.shape == y.shape, k
        assert np.array_equal(x.view(np.uint8), y.view(np.uint8)), k


def test_a_replay_with_other_values_is_a_fresh_replay_to_the_bit(tmp_path):
    from leadscrew_sim import load_preset
    from leadscrew_sim.core.params import ScrewParams
    from leadscrew_sim.offline.foreign.replay import ForeignReplay
    from leadscrew_sim.offline.options import open_recording
    bag, topic, index = Y._bag(tmp_path, 'velocity', 5, None)
    rec, mapping = open_recording(str(bag)), _mapping(topic, index)
    start = load_preset('tr12x3')
    first = ForeignReplay(mapping, rec, start)
    first.replay({})                                    # its command rows are built
    other = ScrewParams.from_dict(dict(mu_s=0.3, mu_k=0.11, encoder_noise=1e-4,
                                       sensor_seed=99), base=start)
    reused = first.with_params(other)
    assert reused.inputs()[1] is first.inputs()[1]      # the rows are shared, not rebuilt
    fresh = ForeignReplay(mapping, rec, other)
    for interpolate in (False, True):
        _same(reused.replay({}, interpolate=interpolate),
              fresh.replay({}, interpolate=interpolate))
    lossy = ScrewParams.from_dict(dict(fault_command_drop_rate=0.3), base=start)
    rebuilt = first.with_params(lossy)
    assert rebuilt.inputs()[1] is not first.inputs()[1]     # lost commands change them
    _same(rebuilt.replay({}), ForeignReplay(mapping, rec, lossy).replay({}))
    assert not np.array_equal(rebuilt.inputs()[1], first.inputs()[1], equal_nan=True)
