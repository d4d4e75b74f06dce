"""
Backlash in the commissioning fit: from the reversals part, with a linear scale.

A horizontal tr12x3 (no load holds the nut on one flank) with a play of
0.2 mm chosen here, a 16-bit encoder and a 0.1 um scale with noise, records
``excite commission``; ``commission`` fits the backlash on the recording up
to the reversals' end with the friction held at its fit. Oracle: the value
chosen here must lie in the reported 95 % interval, and fit.yaml must carry
it (and load in ``simulate --params``).
"""
from helpers import cli_ok
import json
import yaml

#: The play of the axis [m].
BACKLASH = 2e-4


def test_commission_fits_the_backlash_of_the_reversals(tmp_path):
    """The interval holds the true play; fit.yaml holds the value; the report marks it fitted."""
    run = tmp_path / 'run.mcap'
    cli_ok('simulate', '--preset', 'tr12x3', '--excite', 'commission', '--set', 'inclination=0',
           '--set', f'backlash={BACKLASH}', '--set', 'encoder_counts=65536',
           '--set', 'scale_resolution=1e-7', '--set', 'scale_noise=2e-7',
           '--set', 'sensor_seed=3', '-q', '-o', run, timeout=120)
    out = tmp_path / 'out'
    cli_ok('commission', run, '-o', out, '--set', 'inclination=0', '-q', timeout=900)
    section = json.loads((out / 'report.json').read_text())['sections']['backlash']
    assert section['backlash_fitted'], section
    fit = section['backlash_fit']
    assert fit['verdict'] == 'identified', fit
    assert fit['lower'] <= BACKLASH <= fit['upper'], fit
    values = yaml.safe_load((out / 'fit.yaml').read_text())['/**']['ros__parameters']
    assert abs(values['backlash'] - fit['value']) <= 1e-12, values
    cli_ok('simulate', '--params', out / 'fit.yaml', '--duration', '0.01', '-q',
           '-o', tmp_path / 'check.mcap')
