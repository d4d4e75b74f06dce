"""
``leadscrew_sim identify`` on recordings that cannot support every parameter.

The oracles are physical, not the verdicts of identify's own report: a nut
driven one way at constant speed never changes thread flank, so the run
cannot determine the backlash; an axis under zero torque holds still, so
its recording determines no friction and no backlash, whether its sensors
are ideal (exact data) or a 16-bit encoder with noise; a torque well inside
the static band never breaks the thread away, so the static friction is
only bounded; one sliding speed gives one friction torque, which the
Stribeck velocity and the viscous slope cannot be told from.
"""
import importlib
import io

from helpers import cli_ok
from leadscrew_sim import load_preset
from leadscrew_sim.io.mcap_reader import Recording
from leadscrew_sim.offline.identify.progress import FitProgress
import numpy as np
import pytest
import yaml

#: A 16-bit motor encoder with noise of about one count.
NOISY = ('--set', 'encoder_counts=65536', '--set', 'encoder_noise=5e-5')


@pytest.fixture(scope='module')
def recordings(tmp_path_factory):
    """Return the recordings: one-way motion (noisy encoder), still (ideal and noisy)."""
    tmp = tmp_path_factory.mktemp('trust')
    out = {'forward': tmp / 'forward.mcap', 'still': tmp / 'still.mcap',
           'still_noisy': tmp / 'still_noisy.mcap'}
    cli_ok('simulate', '--preset', 'tr12x3', '--velocity', 0.002, '--duration', 1.5, *NOISY,
           '-q', '-o', out['forward'])
    cli_ok('simulate', '--preset', 'tr12x3', '--duration', 2, '-q', '-o', out['still'])
    cli_ok('simulate', '--preset', 'tr12x3', '--duration', 2, *NOISY, '-q', '-o',
           out['still_noisy'])
    return out


def _values(path):
    """Return the ros__parameters of a parameter file, parsed by PyYAML."""
    return yaml.safe_load(path.read_text())['/**']['ros__parameters']


def test_params_file_holds_only_identified_values(recordings, tmp_path):
    """One-way motion: the backlash is left out of the file (named), --write-all writes it."""
    only, every = tmp_path / 'only.yaml', tmp_path / 'all.yaml'
    fit = ('--fit', 'mu_k,backlash', '-q')
    cli_ok('identify', recordings['forward'], *fit, '--output-params', only)
    values = _values(only)
    assert 'backlash' not in values
    assert values.get('preset') == 'tr12x3'
    assert set(values) <= {'preset', 'mu_k'}
    comments = [line for line in only.read_text().splitlines() if line.startswith('#')]
    assert any(line.lstrip('# ').startswith('backlash:') for line in comments), comments
    cli_ok('identify', recordings['forward'], *fit, '--output-params', every, '--write-all')
    values = _values(every)
    assert values['backlash'] == 1e-4                 # the preset's, kept
    assert 'lead_angle' not in values and 'mu_s' in values
    row = next(line for line in every.read_text().splitlines()
               if line.strip().startswith('backlash:'))
    assert '# not identified' in row, row


def test_still_axis_exact_data_identifies_nothing(recordings):
    """Ideal sensors, axis at rest: no verdict 'identified', no '+-0 %'; no progress off a tty."""
    r = cli_ok('identify', recordings['still'])
    assert not any(line.rstrip().endswith('  identified') for line in r.stdout.splitlines())
    assert 'identified:' not in r.stdout, r.stdout
    assert 'exact data' in r.stdout and '+-0 %' not in r.stdout
    # stderr is a pipe: no progress (a first run may say that the kernel compiles)
    assert 're-simulations' not in r.stderr and '\x1b[K' not in r.stderr, r.stderr


def test_still_axis_noisy_identifies_nothing(recordings, tmp_path):
    """A 16-bit encoder with noise, axis at rest: no verdict 'identified'; -q prints nothing."""
    report = tmp_path / 'report.txt'
    r = cli_ok('identify', recordings['still_noisy'], '-q', '--report', report)
    assert r.stdout == '' and r.stderr == ''
    text = report.read_text()
    verdicts = [line for line in text.splitlines() if line.startswith(('mu_', 'stribeck',
                                                                       'backlash ', 'bearing',
                                                                       'guide'))]
    assert len(verdicts) == 7, text
    assert not any(line.rstrip().endswith('  identified') for line in verdicts), text


class _Tty(io.StringIO):
    """A text stream that says it is a terminal."""

    def isatty(self):
        return True


def test_progress_only_on_a_terminal():
    """The status line: drawn on a tty (stage, re-simulations, RMS/sigma), not elsewhere."""
    tty, pipe = _Tty(), io.StringIO()
    for stream in (tty, pipe):
        p = FitProgress(stream, interval=0.0)
        p.update('fit', 12, {'screw_angle': 1.5})
        p.update('fit', 13, {'screw_angle': 1.25})
        p.done()
    assert pipe.getvalue() == ''
    text = tty.getvalue()
    assert 'fit; 13 re-simulations; RMS/sigma screw_angle 1.25' in text
    assert text.endswith('\r\x1b[K')


#: A 16-bit encoder with noise of about one count and a 1 um scale with half a um of noise.
SENSORS = ('--set', 'encoder_counts=65536', '--set', 'encoder_noise=5e-5',
           '--set', 'scale_resolution=1e-6', '--set', 'scale_noise=5e-7')

#: The degenerate motions: (preset, simulate's input and truth, fitted parameters, the
#: parameters the motion cannot determine -> a phrase of the reason).
#: - one_way: the nut driven up at 2 mm/s (against the payload's weight) for 1.5 s: the
#:   load never reverses, so the thread stays on one flank;
#: - inside_band: stick_slip's coupling wound by torques of -0.12 and +0.08 N m, a quarter
#:   of its static band's edges (-0.43 and +0.22 N m by the quasi-static closed form): the
#:   thread never breaks away, only the motor moves;
#: - one_speed: the nut held at 5 mm/s (thread sliding at 55 mm/s, 55 Stribeck velocities),
#:   the preset's friction.
DEGENERATE = {
    'one_way': ('tr12x3', ('--velocity', 0.002, '--set', 'mu_k=0.12'),
                'mu_k,backlash', {'backlash': 'load never reverses'}),
    'inside_band': ('stick_slip', ('--torque-csv', 'band.csv', '--set', 'mu_s=0.35'),
                    'mu_s,mu_k', {'mu_s': 'never breaks away', 'mu_k': 'never slid'}),
    'one_speed': ('tr12x3', ('--velocity', 0.005),
                  'mu_k,stribeck_velocity,mu_viscous',
                  {'stribeck_velocity': 'single speed', 'mu_viscous': 'single speed'}),
}


@pytest.fixture(scope='module')
def degenerate(tmp_path_factory):
    """Return case -> (recording, fit_recording's result) of each degenerate motion (once)."""
    tmp = tmp_path_factory.mktemp('degenerate')
    t = np.linspace(0.0, 1.5, 151)
    torque = np.interp(t, [0.0, 0.5, 1.0, 1.25, 1.5], [0.0, -0.12, 0.0, 0.08, 0.0])
    (tmp / 'band.csv').write_text(''.join(f'{float(a)!r},{float(b)!r}\n'
                                          for a, b in zip(t, torque)))
    main = importlib.import_module('leadscrew_sim.cli.main')
    from leadscrew_sim.offline.identify.run import fit_recording
    out = {}
    for case, (preset, inputs, fit, _why) in DEGENERATE.items():
        inputs = [str(tmp / a) if str(a).endswith('.csv') else a for a in inputs]
        for noisy in (False, True):
            rec = tmp / f'{case}_{int(noisy)}.mcap'
            cli_ok('simulate', '--preset', preset, *inputs, '--duration', 1.5, '-q', '-o',
                   rec, *(SENSORS if noisy else ()))
            args = main.build_parser().parse_args(['identify', str(rec), '--fit', fit])
            out[case, noisy] = rec, fit_recording(args)
    return out


@pytest.mark.parametrize('noisy', (False, True), ids=('exact', 'noisy'))
@pytest.mark.parametrize('case', sorted(DEGENERATE))
def test_a_degenerate_motion_leaves_its_parameter_not_identifiable(degenerate, case, noisy):
    """Each parameter the motion cannot show: 'not identifiable', the reason, its start."""
    preset, _inputs, _fit, why = DEGENERATE[case]
    rec, out = degenerate[case, noisy]
    res, start = out['res'], load_preset(preset)
    for name, phrase in why.items():
        vd = res.verdict(name)
        assert vd.status == 'not identifiable' and not vd.fitted, (name, vd)
        assert vd.reason.startswith('not identifiable: the ') and phrase in vd.reason, vd
        assert res.value(name) == getattr(start, name)
    params = out['params']
    for name in why:
        assert getattr(params, name) == getattr(start, name)
    if case == 'inside_band':
        # the oracle that the thread never broke away: the scale readings spread as their
        # noise and resolution do (sigma 0.58 um; 1.5 sigma allows for the spread's own
        # scatter), or not at all on ideal sensors; a breakaway would move the nut by mm
        x = _joint_positions(rec, 'nut_joint')
        assert np.std(x) <= 1.5 * 5.8e-7, np.std(x)
    else:
        # the kinetic friction, which the sliding does show, is fitted within the issue's
        # 1 % (one_way: the truth 0.12 is 20 % from the start 0.15; one_speed: the preset's
        # 0.15, as the drive loop's spread at another friction is heavy-tailed and one seed
        # of it, which weights the fit, can fall short of the recording's)
        truth = 0.12 if case == 'one_way' else start.mu_k
        assert res.verdict('mu_k').fitted
        assert abs(res.value('mu_k') - truth) <= 0.01 * truth


def _joint_positions(path, joint):
    """Return the recorded positions [m] of ``joint`` in the joint states of a recording."""
    from leadscrew_sim.io import cdr
    rec = Recording(path)
    topic = next(t for t, ty in rec.topic_types.items() if ty == 'sensor_msgs/msg/JointState'
                 and t.endswith('joint_states'))
    out = []
    for _t, tp, data in rec.messages:
        if tp == topic:
            _s, names, pos, _v, _e = cdr.decode_joint_state(data)
            out.append(pos[list(names).index(joint)])
    return np.array(out)
