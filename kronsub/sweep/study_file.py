"""A sweep file (``kronsub sweep STUDY.yaml``): the model, its scene, method, tolerances, axes
and outputs of a sweep under one top-level key ``sweep:``, so a study is kept and rerun as a
file. Paths are relative to the file. Each value is read as the command line reads it; a
problem is reported at its line and column.

    sweep:
      model: ../models/hoffmann/system1.yaml
      scene: free
      t: 10
      grid: {theta: "-3:3:60", phi: "-3:3:60"}
      summaries: {flip: "first_time(abs(phi) > pi)"}
      output: flip.parquet
      trajectories: flip-rows.parquet   # optional: every run's rows
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from ..errors import Location, ModelError, Problem, near_names
from ..model.source import Node, load_yaml

__all__ = ["KEYS", "Study", "is_study", "read_study"]

KEYS = {  # key: (kind, what it is)
    "model": ("path", "the model file"), "scene": ("text", "the scene"), "method": ("text", "the method"),
    "rtol": ("number", "the relative tolerance"), "atol": ("number", "the absolute tolerance"),
    "t": ("number", "the end time"), "dt": ("number", "the output interval"),
    "grid": ("mapping", "grids: NAME: a:b:n, log:a:b:n or a list"),
    "sample": ("mapping", "distributions: NAME: uniform(a, b) ..."), "runs": ("integer", "draws of the samples"),
    "seed": ("integer", "the seed"), "latin": ("flag", "a Latin hypercube"),
    "set": ("mapping", "fixed values: NAME: value"), "summaries": ("mapping", "outputs: NAME: max(...) ..."),
    "chunk": ("integer", "runs per task"), "output": ("path", "the output folder"),
    "trajectories": ("path", "the folder of every run's rows"),
    "table": ("path", "a table of runs, CSV or Parquet"),
}


@dataclass
class Study:
    """The values of a sweep file, by key, and where each was written."""

    path: Path
    values: dict = field(default_factory=dict)
    where: dict = field(default_factory=dict)


def is_study(path: Path) -> bool:
    """Whether ``path`` is a YAML file with a top-level ``sweep:`` (a model never has one)."""
    try:
        root = load_yaml(path, only={})
    except (ModelError, OSError):
        return False
    return root.is_mapping and "sweep" in root.value


def _scalar_text(node: Node) -> str:
    return node.text if node.text is not None else str(node.value)


def read_study(path: Path) -> Study:
    """The sweep file at ``path``; raises :class:`ModelError` with every problem."""
    root = load_yaml(path)
    study = Study(Path(path))
    problems = []
    body = root.get("sweep")
    if body is None or not body.is_mapping:
        raise ModelError([Problem(root.location, "a sweep file holds a mapping under `sweep:`",
                                  "write sweep: then model:, grid:, ... indented under it")])
    extra = [k for k in root.value if k != "sweep"]
    for key in extra:
        problems.append(Problem(root.key_locations[key], f"unknown key '{key}' beside `sweep:`",
                                "put everything under sweep:"))
    for key, node in body.value.items():
        at = body.key_locations.get(key, node.location)
        if key not in KEYS:
            near = near_names(key, set(KEYS))
            problems.append(Problem(at, f"unknown key '{key}' of a sweep file",
                                    ("did you mean " + ", ".join(near) + "?") if near else "keys: " + ", ".join(KEYS)))
            continue
        kind, what = KEYS[key]
        study.where[key] = node.location
        if kind == "mapping":
            if not node.is_mapping:
                problems.append(Problem(node.location, f"{key} must be a mapping ({what})", None))
                continue
            entries = {}
            for name, value in node.value.items():
                if value.is_sequence and key == "grid":
                    entries[name] = "[" + ", ".join(_scalar_text(v) for v in value.value) + "]"
                elif value.is_scalar and value.value is not None:
                    entries[name] = _scalar_text(value)
                else:
                    problems.append(Problem(value.location, f"{key} {name}: expected a value ({what})", None))
                    continue
                study.where[(key, name)] = value.location
            study.values[key] = entries
        elif not node.is_scalar or node.value is None:
            problems.append(Problem(node.location, f"{key} must be {what}", None))
        elif kind == "number":
            if isinstance(node.value, bool) or not isinstance(node.value, (int, float)):
                problems.append(Problem(node.location, f"{key} must be a number ({what}), not {node.text!r}", None))
            else:
                study.values[key] = float(node.value)
        elif kind == "integer":
            if isinstance(node.value, bool) or not isinstance(node.value, int):
                problems.append(Problem(node.location, f"{key} must be a whole number ({what})", None))
            else:
                study.values[key] = int(node.value)
        elif kind == "flag":
            if not isinstance(node.value, bool):
                problems.append(Problem(node.location, f"{key} must be true or false ({what})", None))
            else:
                study.values[key] = node.value
        elif kind == "path":
            study.values[key] = Path(path).parent / _scalar_text(node)
        else:
            study.values[key] = _scalar_text(node)
    if "model" not in study.values and not any(p.message.startswith("model") for p in problems):
        problems.append(Problem(body.location, "a sweep file names its model", "add model: path/to/model.yaml"))
    if problems:
        raise ModelError(problems)
    return study


def location_of(study: Study, key, name: str | None = None) -> Location | None:
    return study.where.get((key, name) if name is not None else key)
