"""
The events ``simulate``, ``info`` and ``resim`` print: what happened to the axis, and when.

One ``simulate`` run drives the nut of tr12x3 with 0.3 N m into its min end
stop through a min limit switch, and a ``--faults`` schedule injects and
removes an encoder freeze and a drive fault, whose latched fault is then
cleared. The expected times come from the schedule the test writes and from
the columns of ``LeadScrewModel.run`` of the same inputs, run here: the
state after step k is at (k + 1) dt; a printed time may differ by one tick.
"""
import re

from helpers import cli_ok
import numpy as np
import pytest

from leadscrew_sim.analysis.events import run_events
from leadscrew_sim.core.model import LeadScrewModel
from leadscrew_sim.core.presets import load_preset

DT = 1e-3
#: Motor torque [N m]: it runs the axis past the preset's overspeed trip, off here
#: (max_screw_velocity 0).
TORQUE = 0.3
LIMIT_MIN = -0.15
#: (time [s], parameter, value) of the schedule; all on whole steps.
SCHEDULE = [(0.3, 'fault.encoder_freeze', 'true'), (0.4, 'fault.encoder_freeze', 'false'),
            (0.5, 'fault.drive_fault', 'true'), (0.6, 'fault.drive_fault', 'false'),
            (0.7, 'clear_fault', 'true')]
EVENT_LINE = re.compile(r'^\s+(-?\d+\.\d+) s  (.+)$')


def _events(stdout):
    """Return [(time [s], text)] of the ``events:`` lines of a verb's output."""
    lines = stdout.splitlines()
    start = next(i for i, line in enumerate(lines) if line.startswith('events:'))
    out = []
    for line in lines[start + 1:]:
        m = EVENT_LINE.match(line)
        if not m:
            break
        out.append((float(m.group(1)), m.group(2)))
    return out


def _oracle():
    """Return {event text: time [s]} from the model's own columns of the scheduled run."""
    p = load_preset('tr12x3', limit_min_position=LIMIT_MIN, max_screw_velocity=0.0)
    model = LeadScrewModel(p, dt=DT)
    cuts = [0] + [round(t / DT) for t, _n, _v in SCHEDULE] + [1000]
    parts = []
    for i, (k0, k1) in enumerate(zip(cuts, cuts[1:])):
        if i:
            _t, name, value = SCHEDULE[i - 1]
            if name == 'clear_fault':
                model.clear_fault()
            else:
                field = name.replace('.', '_')
                model.set_params(p.__class__.from_dict({field: value == 'true'},
                                                       base=model.params))
        if k1 > k0:
            parts.append(model.run(np.full(k1 - k0, TORQUE), drive_values=True))
    names = ('nut_position', 'limit_min', 'fault')
    cols = {n: np.concatenate([c[n] for c in parts]) for n in names}
    t = (np.arange(len(cols['fault'])) + 1) * DT
    latched = int(np.argmax(cols['fault'] != 0))
    cleared = latched + int(np.argmax(cols['fault'][latched:] == 0))
    assert cols['fault'][latched] != 0 and cols['fault'][cleared] == 0
    assert cols['limit_min'].any() and (cols['nut_position'] < p.stroke_min).any()
    return {
        'limit switch min tripped': t[np.argmax(cols['limit_min'])],
        f'end stop reached at stroke_min ({p.stroke_min:g} m)':
            t[np.argmax(cols['nut_position'] < p.stroke_min)],
        'drive fault latched: injected': t[latched],
        'drive fault cleared: injected': t[cleared],
        'injected fault fault.encoder_freeze on': SCHEDULE[0][0],
        'injected fault fault.encoder_freeze off': SCHEDULE[1][0],
        'injected fault fault.drive_fault on': SCHEDULE[2][0],
        'injected fault fault.drive_fault off': SCHEDULE[3][0],
    }


def _check(printed, expected):
    """Assert that ``printed`` lists each expected event once, within one tick of its time."""
    texts = [text for _t, text in printed]
    for text, t in expected.items():
        assert texts.count(text) == 1, (text, printed)
        got = printed[texts.index(text)][0]
        assert abs(got - t) <= DT + 1e-9, (text, got, t)
    assert len(printed) == len(expected), printed


@pytest.fixture(scope='module')
def scheduled_run(tmp_path_factory):
    """Run the scheduled simulate once; return (its output, its file)."""
    d = tmp_path_factory.mktemp('events')
    faults = d / 'faults.csv'
    rows = ''.join(f'{t},{n},{v}\n' for t, n, v in SCHEDULE)
    faults.write_text('time,parameter,value\n' + rows)
    out = d / 'run.mcap'
    r = cli_ok('simulate', '--preset', 'tr12x3', '--torque', TORQUE, '--duration', 1.0,
               '--set', f'limit_min_position={LIMIT_MIN}', '--set', 'max_screw_velocity=0.0',
               '--faults', faults, '--quiet', '--output', out)
    return r.stdout, out


def test_simulate_and_info_print_each_event_at_its_time(scheduled_run):
    """simulate, info (re-simulated) and resim list every event within one tick of the model's."""
    stdout, out = scheduled_run
    expected = _oracle()
    _check(_events(stdout), expected)
    _check(_events(cli_ok('info', out, '--quiet').stdout), expected)
    _check(_events(cli_ok('resim', out, '--quiet', '--output',
                          out.with_name('re.mcap')).stdout), expected)


def test_info_without_resim_reads_the_recording(scheduled_run):
    """With --no-resim, info reads the end stop from sim/joint_states, faults from updates."""
    _stdout, out = scheduled_run
    expected = {k: v for k, v in _oracle().items()
                if k.startswith(('end stop', 'injected'))}
    _check(_events(cli_ok('info', out, '--quiet', '--no-resim').stdout), expected)


def test_quiet_run_prints_no_event(tmp_path):
    """A run with no end stop, switch, fault or timeout prints ``events: none``."""
    out = tmp_path / 'quiet.mcap'
    r = cli_ok('simulate', '--preset', 'tr12x3', '--torque', 0.05, '--duration', 0.2,
               '--quiet', '--output', out)
    assert 'events: none' in r.stdout and _events(r.stdout) == []
    r = cli_ok('info', out, '--quiet')
    assert 'events: none' in r.stdout and _events(r.stdout) == []


def test_bounces_and_staleness_are_one_event_each():
    """A nut bouncing on its stop is one contact; a stale stretch one stale and one resumed."""
    t = np.arange(1, 1001) * DT
    x = np.zeros(1000)
    x[100:500:20] = 0.2 + 1e-6             # on the stop every 20 ms for 1 ms: one contact
    stale = np.zeros(1000, dtype=bool)
    stale[600:700] = True
    events = run_events(t, x, (-0.2, 0.2), stale=stale, settle=0.05)
    assert [(round(e.time, 6), e.kind) for e in events] == [
        (0.101, 'end_stop_on'), (0.482, 'end_stop_off'),
        (0.601, 'command_on'), (0.701, 'command_off')]
