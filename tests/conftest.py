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


def explicit_model_paths() -> list[str]:
    """Bundled models without `constraints:`: the generic checks over every model need explicit
    equations; the closed loops have their own (tests/test_constraints*.py)."""
    import yaml

    out = []
    for p in MODELS.rglob("*.yaml"):
        data = yaml.safe_load(p.read_text(encoding="utf-8"))
        if not (isinstance(data, dict) and data.get("constraints")):
            out.append(str(p.relative_to(MODELS)))
    return sorted(out)
