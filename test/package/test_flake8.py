"""ament flake8 style check, as ROS packages run it."""
from ament_flake8.main import main_with_errors
from helpers import REPO
import pytest


@pytest.mark.flake8
@pytest.mark.linter
def test_flake8():
    paths = [str(REPO / p) for p in ('leadscrew_sim', 'test', 'bench', 'launch', 'setup.py')]
    rc, errors = main_with_errors(argv=paths)
    assert rc == 0, 'Found %d code style errors / warnings:\n' % len(errors) + \
        '\n'.join(errors)
