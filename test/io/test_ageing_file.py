"""
The ageing state file: written atomically, refused when damaged or of another axis.

The oracle of "atomic" is the file system's: a reader never finds the target
half-written, because the new bytes go to a temporary file renamed over it;
a file cut at any byte (as a power cut might leave a non-atomic writer's) is
refused by the JSON parser or the digest.
"""
import json

import pytest

from leadscrew_sim.core.model import LeadScrewModel
from leadscrew_sim.core.presets import load_preset
from leadscrew_sim.io.ageing_file import AgeingFileError, read_state, write_state


@pytest.fixture
def axis():
    p = load_preset('tr12x3')
    state = dict(LeadScrewModel(p).ageing_state(), wear_leading_a=3.25e-5, lubricant=0.4125,
                 screw_temperature=31.5)
    return p, state


def test_a_state_round_trips_exactly(tmp_path, axis):
    p, state = axis
    path = tmp_path / 'axis.json'
    write_state(path, state, p, 'tr12x3', 12.5)
    assert read_state(path, p, 'tr12x3') == state
    assert [f.name for f in tmp_path.iterdir()] == ['axis.json']   # no temporary left


def test_every_cut_of_the_file_is_refused(tmp_path, axis):
    p, state = axis
    path = tmp_path / 'axis.json'
    write_state(path, state, p, 'tr12x3')
    whole = path.read_bytes()
    for n in range(0, len(whole), 7):
        path.write_bytes(whole[:n])
        with pytest.raises(AgeingFileError, match='axis.json'):
            read_state(path, p, 'tr12x3')


def test_a_changed_value_breaks_the_digest(tmp_path, axis):
    p, state = axis
    path = tmp_path / 'axis.json'
    write_state(path, state, p, 'tr12x3')
    body = json.loads(path.read_text())
    body['state']['lubricant'] = 1.0
    path.write_text(json.dumps(body))
    with pytest.raises(AgeingFileError, match='damaged'):
        read_state(path, p, 'tr12x3')


def test_a_file_of_another_preset_or_axis_is_refused(tmp_path, axis):
    p, state = axis
    path = tmp_path / 'axis.json'
    write_state(path, state, p, 'tr12x3')
    with pytest.raises(AgeingFileError, match="preset 'tr12x3', this axis is 'tr8x8'"):
        read_state(path, load_preset('tr8x8'), 'tr8x8')
    with pytest.raises(AgeingFileError, match='another axis.*pitch'):
        read_state(path, p.replace(pitch=0.004), 'tr12x3')
    with pytest.raises(AgeingFileError, match='cannot read'):
        read_state(tmp_path / 'none.json', p, 'tr12x3')


def test_a_write_cut_half_way_leaves_the_old_file(tmp_path, axis, monkeypatch):
    """A writer stopped mid-file (here json.dump raises after half the bytes) changes nothing."""
    p, state = axis
    path = tmp_path / 'axis.json'
    write_state(path, state, p, 'tr12x3')
    before = path.read_bytes()
    real_dump = json.dump

    def half_dump(obj, fh, **kw):
        text = json.dumps(obj, **kw)
        fh.write(text[:len(text) // 2])
        raise KeyboardInterrupt('power cut')

    monkeypatch.setattr(json, 'dump', half_dump)
    with pytest.raises(KeyboardInterrupt):
        write_state(path, dict(state, lubricant=0.1), p, 'tr12x3')
    monkeypatch.setattr(json, 'dump', real_dump)
    assert path.read_bytes() == before
    assert read_state(path, p, 'tr12x3') == state
    assert [f.name for f in tmp_path.iterdir()] == ['axis.json']
