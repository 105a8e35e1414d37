"""What the library holds, as plain data: component types from ``kronsub.components.REGISTRY``,
effect types from the effect registry (``kronsub.model.effects.BUILDERS``) and the joints of
``constraints:`` (``kronsub.model.constraints.JOINT_KEYS``), with the
descriptions and required keys of the packaged JSON schema (which the tests keep in step
with both registries). Read by ``kronsub components``.
"""
from __future__ import annotations

import inspect
import json
import re
from functools import lru_cache
from importlib import resources

import sympy

from ..components import REGISTRY
from ..model.constraints import JOINT_KEYS
from ..model.effects import BUILDERS

WORLD = {0: "none", 1: "line", 2: "plane", 3: "space"}
ROLE = re.compile(r":(?:py:)?[a-z]+:`~?([^`]+)`")  # :func:`name`, :class:`~a.B`, :ref:`text <target>`
LITERAL = re.compile(r"``(.+?)``")


def plain_docstring(doc: str) -> str:
    """A docstring as the terminal shows it: Sphinx roles and ````literals```` as `name`."""
    def role(match: re.Match) -> str:
        text = match.group(1)
        return f"`{text.split('<')[0].strip() if '<' in text else text.rsplit('.', 1)[-1]}`"

    return LITERAL.sub(r"`\1`", ROLE.sub(role, inspect.cleandoc(doc)))


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
        "conventions": plain_docstring(cls.__doc__ or ""),
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


def _joint_branch(name: str) -> dict:
    """The schema's branch of ``constraint`` for one joint: ``{name: ..., description}``."""
    branches = _schema()["$defs"]["constraint"]["oneOf"]
    return next(b for b in branches if b.get("required") == [name])["properties"][name]


def joint(name: str) -> dict:
    """One joint of ``constraints:``: what it holds to, its form and keys (required ones marked)."""
    branch = _joint_branch(name)
    required = set(branch.get("required", ()))
    props = branch.get("properties", {})
    keys = [{"name": k, "required": k in required, "description": props.get(k, {}).get("description", "")}
            for k in JOINT_KEYS[name]]
    if keys:
        form = f"{name}: {{" + ", ".join(f"{k['name']}: ..." for k in keys if k["required"]) + "}"
    else:
        form = f"{name}: [P, Q]"
    return {"type": name, "kind": "joint", "summary": branch.get("description", ""), "form": form, "keys": keys}


def catalogue() -> dict:
    """Every component type, effect type and joint, sorted by name."""
    return {"components": [component(n) for n in sorted(REGISTRY)],
            "effects": [effect(n) for n in sorted(BUILDERS)],
            "joints": [joint(n) for n in sorted(JOINT_KEYS)]}


def names() -> list[str]:
    return sorted({*REGISTRY, *BUILDERS, *JOINT_KEYS})


def details(name: str) -> dict:
    """The data of one component type, effect type or joint."""
    return component(name) if name in REGISTRY else joint(name) if name in JOINT_KEYS else effect(name)


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
    lines += ["", "Joints (under `constraints:`, `NAME: {JOINT: ...}`; keys, * required; summary; "
              "or `NAME: expression` for expression = 0):", ""]
    width = max(len(j["type"]) for j in data["joints"])
    for j in data["joints"]:
        keys = ", ".join(k["name"] + ("*" if k["required"] else "") for k in j["keys"]) or "[P, Q]"
        lines.append(f"  {j['type']:<{width}}  {keys}: {j['summary']}")
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
    if name in JOINT_KEYS:
        j = joint(name)
        lines = [f"{name} (joint, under `constraints:`): {j['summary']}", "", f"form: NAME: {{{j['form']}}}"]
        if j["keys"]:
            lines += ["", "keys (* required):"]
            lines += [f"  {k['name']}{'*' if k['required'] else ''}" + (f": {k['description']}" if k["description"]
                                                                         else "") for k in j["keys"]]
        else:
            lines.append("  P, Q: named points (`component.point`) or a fixed place [x, y] / [x, y, z]")
        lines.append("  description: free text (optional, beside the joint)")
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
