"""Moved to tests/reference/mechanics.py; this name stays until the tests that still import it
(test_api.py, test_simulate.py, test_linearize.py) switch to ``from reference import mechanics``."""
import sys

from reference import mechanics

sys.modules[__name__] = mechanics
