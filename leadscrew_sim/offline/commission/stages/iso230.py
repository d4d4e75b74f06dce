"""Stage 'iso230': the ISO 230-2 bidirectional figures of the iso230 part."""
from . import backlash


def run(ctx):
    """Return the ISO 230-2 section (reversal value B per target, mean and max)."""
    section = backlash.run(ctx, part='iso230', title='ISO 230-2')
    section['cannot'] = [c for c in section['cannot'] if 'not fitted' not in c]
    section['cannot'].append('positioning accuracy A and repeatability R need a reference '
                             'instrument (a laser interferometer); the deviations here are '
                             'those of the axis\'s own position sensor')
    return section
