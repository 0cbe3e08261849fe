"""Helpers shared by the tests (strategies, cases, tolerances); not tests.

``tests/`` is on ``sys.path`` during a run (pytest puts the folder of
``conftest.py`` there), so tests import these as ``support.<module>``.
"""

from pathlib import Path

#: The root of the source tree (the checkout, or the unpacked sdist).
ROOT = Path(__file__).resolve().parents[2]
