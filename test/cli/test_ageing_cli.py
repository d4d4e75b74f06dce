"""
The ageing through the verbs: a warm-up run and its plot, a worn axis carried on and replayed.

Oracles: the mcap library reads every file; the drift the plot reports at
the stops is checked against alpha dT (x - x_fixed) from the recorded screw
temperature; a run started ``--ageing-from`` another starts from the state
that run recorded at its end; ``resim`` re-runs it to the same bytes.
"""
import re

from helpers import cli_ok
from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory
import pytest

from leadscrew_sim.analysis.excitation.profiles import make_profile
from leadscrew_sim.core.presets import load_preset
from leadscrew_sim.io.run_file import AGEING_END_RECORD, AGEING_KEY, PARAMS_RECORD

ALPHA = 5e-5          # a large expansion, so the drift dwarfs the servo's landing [1/K]
X_FIXED = -0.12       # the fixed bearing below the stroke [m]
HEAT = ['--set', 'screw_heat_capacity=200', '--set', 'screw_heat_loss=1',
        '--set', 'ageing_speedup=20', '--set', f'thermal_expansion={ALPHA}',
        '--set', f'fixed_bearing_x={X_FIXED}']
WEAR = ['--set', 'wear_rate=1e-9', '--set', 'ageing_speedup=1e4', '--set', 'lubricant_life=5']


def _ageing(path):
    """Return [(log time [ns], AgeingState)] of a file, by the mcap library."""
    with open(path, 'rb') as fh:
        return [(m.log_time, msg) for _s, _c, m, msg in make_reader(
            fh, decoder_factories=[DecoderFactory()]).iter_decoded_messages(
                topics=['/sim/ageing'])]


def _meta(path, name):
    with open(path, 'rb') as fh:
        for m in make_reader(fh).iter_metadata():
            if m.name == name:
                return dict(m.metadata)
    return None


def test_a_warm_up_run_plots_the_drift_of_the_growing_screw(tmp_path):
    """The largest drift at the stops is the growth since the first stop at that position."""
    run = tmp_path / 'warm.mcap'
    cli_ok('simulate', '--excite', 'warmup', '--excite-opt', 'stops=3', '--excite-opt',
           'interval=15', *HEAT, '-q', '-o', run, timeout=300)
    r = cli_ok('plot', run, '-o', tmp_path / 'warm.png', '-q', timeout=300)
    assert (tmp_path / 'warm.png').stat().st_size > 10000
    m = re.search(r'largest ([-+0-9.]+) um at ([-0-9.]+) mm, t = ([0-9.]+) s', r.stdout)
    assert m, r.stdout
    drift, x, t_stop = float(m[1]) * 1e-6, float(m[2]) * 1e-3, float(m[3])
    states = _ageing(run)
    t0 = states[0][0] - 1_000_000             # the first state is one step after the start

    def growth_at(t):
        i = min(range(len(states)), key=lambda k: abs((states[k][0] - t0) / 1e9 - t))
        return ALPHA * (states[i][1].screw_temperature - 20.0) * (x - X_FIXED)

    # the stops of the profile as designed: the first one at x comes before the warm-up;
    # the drift is the growth since then, to within the servo's landing (tenths of a um)
    profile = make_profile('warmup', load_preset('tr12x3'), stops=3, interval=15.0)
    ends = {seg.label: seg.t1 for seg in profile.segments}
    side = 'high' if x > 0 else 'low'
    k = next(k for k in range(1, 4) if abs(ends[f'stop {k} {side}'] - t_stop) < 0.1)
    expected = growth_at(ends[f'stop {k} {side}']) - growth_at(ends[f'stop 0 {side}'])
    assert abs(drift) > 5e-6
    assert drift == pytest.approx(expected, rel=0.1, abs=3e-7)


def test_a_worn_axis_carries_on_and_replays_bit_for_bit(tmp_path):
    first, second = tmp_path / 'first.mcap', tmp_path / 'second.mcap'
    cli_ok('simulate', '--duration', '2', '--velocity', '0.02', *WEAR, '-q', '-o', first)
    cli_ok('simulate', '--duration', '2', '--velocity', '-0.02', *WEAR, '--ageing-from', first,
           '-q', '-o', second)
    end = _meta(first, AGEING_END_RECORD)
    start = _meta(second, PARAMS_RECORD)
    keys = [k for k in end if k.startswith(AGEING_KEY)]
    assert len(keys) == 6 and all(start[k] == end[k] for k in keys)
    last = _ageing(first)[-1][1]
    assert float(end[AGEING_KEY + 'wear_leading_a']) == last.wear_leading > 1e-6
    assert _ageing(second)[0][1].wear_leading >= last.wear_leading
    info = cli_ok('info', first, '--no-resim').stdout
    m = re.search(r'ageing: wear leading \S+ -> (\S+) um', info)
    assert m and float(m[1]) == pytest.approx(last.wear_leading * 1e6, rel=1e-3), info
    replay = tmp_path / 'replay.mcap'
    r = cli_ok('resim', second, '-q', '-o', replay)
    assert 'bit-identical' in r.stdout
    assert [(t, m.wear_leading, m.lubricant, m.screw_temperature)
            for t, m in _ageing(second)] == [(t, m.wear_leading, m.lubricant,
                                              m.screw_temperature)
                                             for t, m in _ageing(replay)]


def test_ageing_from_a_recording_of_another_axis_is_refused(tmp_path):
    first = tmp_path / 'tr8.mcap'
    cli_ok('simulate', '--preset', 'tr8x8', '--duration', '0.1', '-q', '-o', first)
    from helpers import cli
    r = cli('simulate', '--duration', '0.1', '--ageing-from', first, '-q',
            '-o', tmp_path / 'x.mcap')
    assert r.returncode != 0 and 'Traceback' not in r.stderr
    assert 'another axis' in r.stderr and 'tr8.mcap' in r.stderr, r.stderr
    assert not (tmp_path / 'x.mcap').exists()


def test_a_negative_wear_rate_is_refused_by_the_verb(tmp_path):
    from helpers import cli
    r = cli('simulate', '--duration', '0.1', '--set', 'wear_rate=-1e-9', '-q',
            '-o', tmp_path / 'x.mcap')
    assert r.returncode != 0 and 'Traceback' not in r.stderr
    assert "'wear_rate': -1e-09 m/(N m)" in r.stderr and '[0.0, 0.001]' in r.stderr
