"""What the library holds, as plain data: component types from ``kronsub.components.REGISTRY``
and effect types from the effect registry (``kronsub.model.effects.BUILDERS``), with the
descriptions and required keys of the packaged JSON schema (which the tests keep in step
with both registries). Read by ``kronsub components``.
"""
from __future__ import annotations

import inspect
import json
from functools import lru_cache
from importlib import resources

import sympy

from ..components import REGISTRY
from ..model.effects import BUILDERS

WORLD = {0: "none", 1: "line", 2: "plane", 3: "space"}


@lru_cache(maxsize=1)
def _schema() -> dict:
    return json.loads(resources.files("kronsub.model").joinpath("schema.json").read_text("utf-8"))


def _points(cls) -> dict[str, tuple[str, ...]]:
    """Named points of a component bound to symbols of its own names, as text."""
    x = {name: sympy.Symbol(name, real=True) for name in cls.coordinates}
    p = {spec.name: sympy.Symbol(spec.name, real=True) for spec in cls.parameters}
    return {name: tuple(sympy.sstr(c, order="lex") for c in position)
            for name, position in cls(x=x, p=p).points().items()}


def component(name: str) -> dict:
    """One component type: coordinates, parameters, named points, world and conventions."""
    cls = REGISTRY[name]
    return {
        "type": name,
        "kind": "component",
        "summary": cls.summary,
        "conventions": inspect.cleandoc(cls.__doc__ or ""),
        "coordinates": list(cls.coordinates),
        "parameters": [{"name": s.name, "description": s.description, "default": s.default, "unit": s.unit}
                       for s in cls.parameters],
        "points": {k: list(v) for k, v in _points(cls).items()},
        "world": WORLD[cls.dimension],
        "takes_points": cls.rigid,
    }


def effect(name: str) -> dict:
    """One effect type: what it computes and its keys (required ones marked)."""
    _, keys = BUILDERS[name]
    branch = _schema()["$defs"].get(f"effect_{name}", {})
    required = set(branch.get("required", ())) - {"type"}
    props = branch.get("properties", {})
    one_of = [sorted(set(alt.get("required", ()))) for alt in branch.get("anyOf", ())]
    return {
        "type": name,
        "kind": "effect",
        "summary": branch.get("description", ""),
        "keys": [{"name": k, "required": k in required, "description": props.get(k, {}).get("description", "")}
                 for k in keys],
        "one_of": one_of,
    }


def catalogue() -> dict:
    """Every component type and effect type, sorted by name."""
    return {"components": [component(n) for n in sorted(REGISTRY)],
            "effects": [effect(n) for n in sorted(BUILDERS)]}


def names() -> list[str]:
    return sorted({*REGISTRY, *BUILDERS})


# ------------------------------------------------------------------------------------------
# Text
# ------------------------------------------------------------------------------------------

def _parameter(p: dict) -> str:
    text = p["name"]
    if p["default"] is not None:
        text += f" = {p['default']}"
    if p["unit"]:
        text += f" [{p['unit']}]"
    return text


def overview_text() -> str:
    data = catalogue()
    lines = ["Components (type: coordinates; world; summary):", ""]
    width = max(len(c["type"]) for c in data["components"])
    for c in data["components"]:
        lines.append(f"  {c['type']:<{width}}  ({', '.join(c['coordinates'])}); {c['world']}; {c['summary']}")
    lines += ["", "Effects (type: keys, * required; summary):", ""]
    width = max(len(e["type"]) for e in data["effects"])
    for e in data["effects"]:
        keys = ", ".join(k["name"] + ("*" if k["required"] else "") for k in e["keys"])
        lines.append(f"  {e['type']:<{width}}  {keys}: {e['summary']}")
    lines += ["", "Details of one: kronsub components TYPE"]
    return "\n".join(lines) + "\n"


def detail_text(name: str) -> str:
    if name in REGISTRY:
        c = component(name)
        lines = [f"{name}: {c['summary']}", "", c["conventions"], "",
                 f"world: {c['world']}" + ("; takes `points:` of its own (body-frame offsets)"
                                          if c["takes_points"] else ""),
                 "coordinates (in order): " + ", ".join(c["coordinates"]), "", "parameters:"]
        for p in c["parameters"]:
            lines.append(f"  {_parameter(p)}: {p['description']}" + ("" if p["default"] is not None
                                                                       else " (required)"))
        lines += ["", "named points (world position):"]
        lines += [f"  {k}: ({', '.join(v)})" for k, v in c["points"].items()] or ["  none"]
        lines += ["", "example:", f"  my_{name}: {{type: {name}, parameters: {{"
                  + ", ".join(f"{p['name']}: ..." for p in c["parameters"] if p["default"] is None) + "}}"]
        return "\n".join(lines) + "\n"
    e = effect(name)
    lines = [f"{name} (effect): {e['summary']}", "", "keys (* required):"]
    for k in e["keys"]:
        lines.append(f"  {k['name']}{'*' if k['required'] else ''}" + (f": {k['description']}" if k["description"]
                                                                        else ""))
    if e["one_of"]:
        lines.append("  needs one of: " + " | ".join(" + ".join(alt) for alt in e["one_of"]))
    lines.append("  description: free text (optional)")
    return "\n".join(lines) + "\n"


__all__ = ["WORLD", "catalogue", "component", "detail_text", "effect", "names", "overview_text"]
