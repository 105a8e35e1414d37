"""Shared fixtures: bundled model paths, and a private known-system cache per test run."""
from __future__ import annotations

from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
MODELS = ROOT / "models"


@pytest.fixture(autouse=True, scope="session")
def _private_cache(tmp_path_factory):
    """Keep the known-system cache of the tests apart from the user's."""
    mp = pytest.MonkeyPatch()
    mp.setenv("KRONSUB_CACHE_DIR", str(tmp_path_factory.mktemp("kronsub-cache")))
    yield
    mp.undo()
