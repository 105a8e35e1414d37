"""``pip install .`` (the README's first command) installs what ``pyproject.toml`` lists, not
what an editable install finds: every folder of ``kronsub/`` with Python files must be listed
(``kronsub.commands`` was not, and ``kronsub derive`` failed to import after ``pip install .``)."""
from __future__ import annotations

import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def test_every_package_folder_is_listed_in_pyproject():
    config = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))
    listed = set(config["tool"]["setuptools"]["packages"])
    folders = {".".join(d.relative_to(ROOT).parts) for d in (ROOT / "kronsub").rglob("*")
               if d.is_dir() and d.name != "__pycache__" and any(d.glob("*.py"))}
    folders.add("kronsub")
    assert folders <= listed, sorted(folders - listed)
    for name, where in config["tool"]["setuptools"].get("package-dir", {}).items():
        assert (ROOT / where).is_dir(), (name, where)


def test_the_package_data_the_code_reads_is_declared():
    config = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))
    data = config["tool"]["setuptools"]["package-data"]
    assert "*.json" in data["kronsub.model"] and list((ROOT / "kronsub" / "model").glob("*.json"))
    assert "*.j2" in data["kronsub.templates"] and list((ROOT / "templates").glob("*.j2"))
    csrc = ROOT / "kronsub" / "simulation" / "csrc"
    suffixes = {p.suffix for p in csrc.iterdir() if p.is_file() and p.suffix != ".py"}
    assert {f"*{s}" for s in suffixes} <= set(data["kronsub.simulation.csrc"]), suffixes
