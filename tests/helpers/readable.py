"""The printed entries of a model's report, and their yardsticks: what ``sympy.trigsimp`` and
``sympy.fu`` make of each (tests/test_readable.py measures against them; tests/data/yardsticks.py
stores them)."""
from __future__ import annotations

import json

import sympy

import kronsub
from conftest import MODELS, ROOT, SLOW_MODELS
from kronsub.emitters.report import build_report, model_names, plain_printer
from kronsub.model.expressions import parse_expression

BUNDLED = sorted(str(p.relative_to(MODELS)) for p in MODELS.rglob("*.yaml")
                 if p.relative_to(ROOT).as_posix() not in SLOW_MODELS)
PARSEABLE = list(BUNDLED)
EXTRA = ["disc_on_incline.yaml", "polar_spring.yaml", "internal_names.yaml"]
_SYSTEMS: dict = {}


def system_of(name: str):
    """The bundled or test model ``name`` derived (once per run)."""
    if name not in _SYSTEMS:
        path = MODELS / name if (MODELS / name).exists() else ROOT / "tests" / "models" / name
        _SYSTEMS[name] = kronsub.load(path).derive()
    return _SYSTEMS[name]


def printed(name: str):
    """(system, report, names): the report in the model's str form, and the names a parser
    needs to read it back (the model's own and the where block's)."""
    system = system_of(name)
    report = build_report(system, plain_printer(model_names(system)))
    everything = [*system.mass_matrix, *system.velocity_terms, *system.forces,
                  system.kinetic_energy, system.potential_energy]
    if system.transition is not None:
        tr = system.transition
        everything += [*tr.primitive_metric, *tr.primitive_velocity_terms, *tr.transformation,
                       *[e for f in tr.primitive_forces.values() for e in f], *[e for _, e in tr.connection]]
    names = {s.name: s for e in everything for s in sympy.sympify(e).free_symbols}
    names.update({p.name: p.symbol for p in system.parameters})
    names.update({a.name: a for a in system.accelerations})
    for w in report["where"]:
        assert w["plain"] not in names, f"{w['plain']} clashes with a name of the model"
        names[w["plain"]] = sympy.Symbol(w["plain"])
    return system, report, names


def entries(report):
    """The printed ``Mbar`` (upper triangle), ``hbar`` and ``fbar`` entries, labelled."""
    n = len(report["mass_matrix"])
    out = [(f"Mbar[{i},{j}]", report["mass_matrix"][i][j]) for i in range(n) for j in range(i, n)]
    out += [(f"hbar[{i}]", e) for i, e in enumerate(report["velocity_terms"])]
    out += [(f"fbar[{i}]", e) for i, e in enumerate(report["forces"])]
    return out


YARDSTICK_OPS = 120
"""Entries up to this many operations are measured against ``trigsimp``, ..."""
FU_OPS = 40
"""... and up to this many against ``fu`` too: its factorisations ran for minutes on System
II's 70-operation ``hbar`` in a full run (seconds alone: it depends on sympy's caches)."""


YARDSTICKS = ROOT / "tests" / "data" / "yardsticks.json"
"""The yardsticks of the entries printed when it was written (``python tests/data/yardsticks.py``
rewrites it), keyed by model, label and printed text, for the sympy version that measured them.
An entry printed otherwise, or another sympy, is measured afresh: the file only saves time."""


def stored_yardsticks() -> dict:
    """The stored yardsticks of ``YARDSTICKS``, for this sympy version (else none)."""
    if not YARDSTICKS.is_file():
        return {}
    data = json.loads(YARDSTICKS.read_text(encoding="utf-8"))
    return data["entries"] if data.get("sympy") == sympy.__version__ else {}


STORED = stored_yardsticks()
"""The yardsticks read from ``YARDSTICKS``; cleared to measure everything afresh."""


def yardstick_key(name: str, label: str, text: str) -> str:
    """The key of an entry: the model, its label and its printed text."""
    return f"{name} {label} {text}"


def yardsticks(expr, key: str | None = None):
    """(trigsimp ops, fu ops) of ``expr``: as stored under ``key``, else measured now."""
    if key is not None and key in STORED:
        return tuple(STORED[key])
    trig = sympy.count_ops(sympy.trigsimp(expr))
    return trig, (sympy.count_ops(sympy.fu(expr)) if sympy.count_ops(expr) <= FU_OPS else trig)


def measured_yardsticks(name: str) -> dict:
    """``{key: (trigsimp ops, fu ops)}`` of the model's entries the test measures, afresh."""
    _, report, names = printed(name)
    out = {}
    for label, text in entries(report):
        expr = parse_expression(text, names)
        if sympy.count_ops(expr) <= YARDSTICK_OPS:
            out[yardstick_key(name, label, text)] = list(yardsticks(expr))
    return out


YARDSTICK_MODELS = PARSEABLE + ["disc_on_incline.yaml"]
