"""The offline command line ``leadscrew_sim``: one module per verb."""
from .verbs import *  # noqa: F401,F403
from .verbs import main  # noqa: F401
