"""ament pep257 docstring check, as ROS packages run it."""
from ament_pep257.main import main
from helpers import REPO
import pytest


@pytest.mark.linter
@pytest.mark.pep257
def test_pep257():
    rc = main(argv=[str(REPO / 'leadscrew_sim'), str(REPO / 'test'), str(REPO / 'bench')])
    assert rc == 0, 'Found code style errors / warnings'
