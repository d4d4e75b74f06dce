"""
The library's resim, excite and info calls, in-process.

Oracles: the mcap library's reading of the two files (the re-simulated
states have the recorded bytes), a changed friction coefficient that must
move the nut, and for a profile the options it was given: the reversals'
extremes are centre plus and minus the amplitude, the warm-up's stops hold
their targets. For info: the mcap library's message counts and mcap_ros2's
decoding of the states; a recording stripped of its records is surveyed,
and its proposals name keywords, not flags.
"""
from mcap.reader import make_reader
import numpy as np
import pytest

import leadscrew_sim as ls


def _states(path, topic='/axis/joint_states'):
    with open(path, 'rb') as fh:
        return [(m.log_time, m.data) for _s, _c, m in make_reader(fh).iter_messages(
            topics=[topic])]


def test_resim_of_a_run_is_bit_identical_and_an_override_is_not(tmp_path):
    run = ls.simulate('tr12x3', duration=0.5, velocity=0.02, output=str(tmp_path / 'a.mcap'))
    same = ls.resim(run.path, output=str(tmp_path / 'b.mcap'))
    assert same.bit_identical and same.ticks == 500
    assert _states(tmp_path / 'a.mcap') == _states(tmp_path / 'b.mcap')
    other = ls.resim(ls.open_recording(run.path), set={'mu_k': 0.2},
                     output=str(tmp_path / 'c.mcap'))
    assert not other.bit_identical
    nut = [r for r in other.rows if r['field'] == 'position[nut_joint]'][0]
    assert nut['max_diff'] > 1e-6 and nut['n'] == 500
    with pytest.raises(ls.LeadscrewError, match="'mu_k'.*-1"):
        ls.resim(run.path, set={'mu_k': -1.0}, output=str(tmp_path / 'd.mcap'))


def test_excite_returns_the_profile_as_arrays():
    e = ls.excite('reversals', opt={'center': 0.01, 'amplitude': 0.002, 'cycles': 2},
                  command_rate=200.0)
    assert e.topic == 'position_command' and e.unit == 'm'
    assert np.allclose(np.diff(e.time), 1 / 200.0)
    moves = e.values[e.time >= e.segments[0][1]]     # after the move from rest to the centre
    assert moves.max() == pytest.approx(0.012) and moves.min() == pytest.approx(0.008)
    w = ls.excite('warmup', opt={'stops': 2, 'interval': 5.0, 'stroke': 0.1, 'center': 0.0})
    stops = [(a, b) for a, b, label in w.segments if label == 'stop 2 high']
    assert len(stops) == 1
    a, b = stops[0]
    held = w.values[(w.time > a + 0.01) & (w.time < b - 0.01)]
    assert len(held) and np.all(held == pytest.approx(0.05))
    with pytest.raises(ls.LeadscrewError, match="'stops'.*-1"):
        ls.excite('warmup', opt={'stops': -1})
    with pytest.raises(ls.LeadscrewError, match='command_rate'):
        ls.excite('warmup', command_rate=0.0)


def test_freqresp_stability_and_pullout_are_calls():
    """Each returns its figures; checked against closed forms of the axis."""
    p = ls.load_preset('tr12x3')
    # a velocity loop that tracks: at low frequency the motor turns 2 pi / lead per m/s
    r = ls.freqresp(linear=True, rest='free', fmin=0.1, fmax=50.0, points=5)[0]
    assert r.input == 'velocity_command' and r.output == 'motor_velocity'
    assert abs(r.response[0]) == pytest.approx(2 * np.pi / p.lead, rel=1e-3)
    # sliding steadily with a velocity-independent friction (mu_s = mu_k, no viscous term)
    # the linear analysis finds no growth: every mode decays
    s = ls.stability(set={'mu_s': p.mu_k}, speed=0.01, method='linear')
    assert s.complete and len(s.rows) == 1 and s.rows[0]['growth_rate'] < 0.0
    # a stepper pulls out below its holding torque, less at the higher rate
    q = ls.load_preset('nema17_tr8x8')
    out = ls.pullout('nema17_tr8x8', rates=[200.0, 1000.0], ramp=1.0)
    assert list(out.step_rate) == [200.0, 1000.0]
    assert 0.0 < out.pullout_torque[1] < out.pullout_torque[0] < q.holding_torque
    with pytest.raises(ls.LeadscrewError, match='grid'):
        ls.stability(grid={'speed': (0.001, 0.01)})


def test_recover_copies_a_whole_file_and_says_what_a_cut_one_lost(tmp_path):
    run = ls.simulate('tr12x3', duration=0.3, velocity=0.02, output=str(tmp_path / 'a.mcap'))
    whole = ls.recover(run.path, str(tmp_path / 'copy.mcap'))
    with open(run.path, 'rb') as fh:
        counts = {}
        for _s, c, _m in make_reader(fh).iter_messages():
            counts[c.topic] = counts.get(c.topic, 0) + 1
    assert whole.whole and whole.topics == counts and whole.lost_bytes == 0
    data = (tmp_path / 'a.mcap').read_bytes()
    (tmp_path / 'cut.mcap').write_bytes(data[:len(data) * 2 // 3])
    cut = ls.recover(str(tmp_path / 'cut.mcap'))
    assert not cut.whole and cut.lost_bytes > 0 and cut.problem
    with open(cut.path, 'rb') as fh:                 # the copy is a complete, readable file
        assert sum(1 for _ in make_reader(fh).iter_messages()) == sum(cut.topics.values())
    with pytest.raises(ls.LeadscrewError, match='exists'):
        ls.recover(str(tmp_path / 'cut.mcap'))


@pytest.mark.parametrize('call, kw, text', [
    ('simulate', {'update_rate': 0.5}, "option 'update_rate': 0.5 Hz is outside the allowed "
     "range [1.0, 1000000.0]"),
    ('simulate', {'duration': -1.0}, "option 'duration': -1.0 s is outside"),
    ('simulate', {'velocity': float('nan')}, "option 'velocity': nan m/s must be a finite"),
    ('freqresp', {'linear': True, 'fmin': -1.0}, "option 'fmin': -1.0 Hz is outside"),
    ('pullout', {'ramp': 0.0}, "option 'ramp': 0.0 s is outside"),
])
def test_a_bad_option_is_named_as_the_keyword_not_the_flag(call, kw, text):
    with pytest.raises(ls.LeadscrewError) as err:
        getattr(ls, call)(**kw)
    assert text in str(err.value) and '--' not in str(err.value)


def test_info_names_what_the_recording_holds(tmp_path):
    """ls.info: the channels as the mcap library counts them, the states' range, the events."""
    run = ls.simulate('tr12x3', duration=0.5, velocity=0.02, output=str(tmp_path / 'a.mcap'))
    r = ls.info(ls.open_recording(run.path), resim=True)
    with open(run.path, 'rb') as fh:
        reader = make_reader(fh)
        summary = reader.get_summary()
        counts = {summary.channels[cid].topic: n
                  for cid, n in summary.statistics.channel_message_counts.items()}
    assert {c.topic: c.count for c in r.channels} == counts
    assert r.leadscrew and r.run['preset'] == 'tr12x3' and r.survey is None
    # the joint states' nut positions, decoded by the tests' own CDR reading (mcap_ros2)
    from bag_factory import sim_states
    _stamps, pos, _vel, _eff = sim_states(run.path)
    assert r.states['nut_final'] == pos[-1, 1]
    assert r.states['nut_min'] == pos[:, 1].min() and r.states['nut_max'] == pos[:, 1].max()
    # 0.5 s at 1 kHz: the rate of the states is the step rate (to the count's rounding)
    js = next(c for c in r.channels if c.topic == '/axis/joint_states')
    assert js.rate == pytest.approx(1000.0, rel=0.01)
    assert r.thread is not None and 0.0 <= r.thread.stick <= 1.0
    assert sum(r.thread.contact.values()) == pytest.approx(1.0)
    assert isinstance(r.events, list)
    with pytest.raises(ls.LeadscrewError, match="figures 'nope'"):
        ls.info(run.path, figures='nope')


def test_info_of_a_foreign_recording_names_the_keywords(tmp_path):
    """A recording without the parameters record: the survey proposes options by keyword."""
    from bag_factory import strip_records
    run = ls.simulate('tr12x3', duration=0.2, velocity=0.02, output=str(tmp_path / 'a.mcap'))
    bare = tmp_path / 'bare.mcap'
    strip_records(run.path, bare)
    r = ls.info(str(bare))
    assert not r.leadscrew and r.survey
    text = '\n'.join(r.survey)
    assert 'command_topic' in text and '--' not in text, text
    assert any('--command-topic' in ln for ln in r.survey_text(lambda k: '--' + k.replace(
        '_', '-'))), r.survey
