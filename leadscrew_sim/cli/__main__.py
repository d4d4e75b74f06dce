"""``python -m leadscrew_sim.cli``."""
import sys

from . import main

sys.exit(main())
