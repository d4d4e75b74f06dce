"""
``leadscrew_sim identify`` on recordings that cannot support every parameter.

The oracles are physical, not the verdicts of identify's own report: a nut
driven one way at constant speed never changes thread flank, so the run
cannot determine the backlash; an axis under zero torque holds still, so
its recording determines no friction and no backlash, whether its sensors
are ideal (exact data) or a 16-bit encoder with noise.
"""
import io

from helpers import cli_ok
from leadscrew_sim.offline.identify_progress import FitProgress
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
