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


REJECTED_MODELS = frozenset({
    "tests/models/sweep/growing_mass.yaml",  # a component's parameter that depends on t
    "tests/models/sweep/pendulum_named_like_columns.yaml",  # a coordinate named like a CSV column
    "tests/models/sweep/shaken_pendulum.yaml",  # a pivot that depends on t
    "tests/models/sweep3/cart_and_pulley.yaml",  # one parameter given two values
})
"""Test model files that exist to be rejected (their tests check the message)."""


SLOW_MODELS = frozenset({
    "models/benchmarks/whipple_bicycle.yaml",  # derived and linearised in seconds; printed, beyond the default budget
})
"""Model files the loops over every model leave out until they print in seconds; each has its own
test (tests/test_whipple_bicycle_file.py: derived and linearised within the default work budget;
its printed Mbar in the coordinates and equations in the speeds are far beyond it)."""


def every_model_file() -> list[Path]:
    """Every bundled and test model file that loads, sorted (:data:`REJECTED_MODELS` and
    :data:`SLOW_MODELS` apart)."""
    files = [*MODELS.rglob("*.yaml"), *(ROOT / "tests" / "models").rglob("*.yaml")]
    return sorted(p for p in files if p.relative_to(ROOT).as_posix() not in REJECTED_MODELS | SLOW_MODELS)


def explicit_model_paths() -> list[str]:
    """Bundled models without `constraints:`, `velocity_constraints:` or `speeds:`: the generic checks
    over every model need explicit equations in qdot; the closed loops have their own
    (tests/test_constraints*.py), the non-holonomic models theirs (tests/test_nonholonomic*.py), a
    change of velocity frame its own (tests/test_park_frame.py)."""
    import yaml

    def constrained(path: Path, seen=()) -> bool:
        """`constraints:` in the file or in a known system it uses (which brings its own)."""
        data = yaml.safe_load(path.read_text(encoding="utf-8"))
        if not isinstance(data, dict):
            return False
        if data.get("constraints") or data.get("velocity_constraints") or data.get("speeds"):
            return True
        for spec in (data.get("components") or {}).values():
            sub = isinstance(spec, dict) and spec.get("model")
            if isinstance(sub, str) and (path.parent / sub).is_file() and (path.parent / sub) not in seen:
                if constrained(path.parent / sub, seen + (path,)):
                    return True
        return False

    return sorted(str(p.relative_to(MODELS)) for p in MODELS.rglob("*.yaml") if not constrained(p)
                  and p.relative_to(ROOT).as_posix() not in SLOW_MODELS)


@pytest.fixture
def cache(tmp_path, monkeypatch):
    """A fresh kronsub cache folder (not yet created) for one test."""
    folder = tmp_path / "cache"
    monkeypatch.setenv("KRONSUB_CACHE_DIR", str(folder))
    return folder
