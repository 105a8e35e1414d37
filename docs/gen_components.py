"""Print the component-library tables of docs/model-format.md from the registry.

    python docs/gen_components.py

Everything printed comes from ``kronsub.components.REGISTRY``: each type's
coordinates (in order), parameters (with defaults and units), world dimension,
summary, and its named points with their world positions (computed by binding
the component to symbols named like its coordinates and parameters).
"""
from __future__ import annotations

import sympy

from kronsub.components import REGISTRY

WORLD = {0: "none", 1: "line", 2: "plane", 3: "space"}


def _parameter(spec) -> str:
    text = f"`{spec.name}`"
    if spec.default is not None:
        text += f" = `{spec.default}`"
    if spec.unit:
        text += f" ({spec.unit})"
    return text


def _points(cls) -> dict[str, tuple[sympy.Expr, ...]]:
    """The named points of a component bound to symbols of its own names."""
    x = {name: sympy.Symbol(name, real=True) for name in cls.coordinates}
    p = {spec.name: sympy.Symbol(spec.name, real=True) for spec in cls.parameters}
    return dict(cls(x=x, p=p).points())


def component_tables() -> str:
    lines = [
        "| type | coordinates (in order) | parameters (= default) | named points | world | summary |",
        "|---|---|---|---|---|---|",
    ]
    for name in sorted(REGISTRY):
        cls = REGISTRY[name]
        coords = ", ".join(f"`{c}`" for c in cls.coordinates)
        params = ", ".join(_parameter(spec) for spec in cls.parameters)
        points = ", ".join(f"`{p}`" for p in _points(cls)) or "none"
        lines.append(f"| `{name}` | {coords} | {params} | {points} | {WORLD[cls.dimension]} | {cls.summary} |")
    lines += [
        "",
        "Named points and their world positions (in the component's own coordinate and",
        "parameter names):",
        "",
        "| type | point | position |",
        "|---|---|---|",
    ]
    for name in sorted(REGISTRY):
        for point, position in _points(REGISTRY[name]).items():
            shown = ", ".join(str(c) for c in position)
            lines.append(f"| `{name}` | `{point}` | `({shown})` |")
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    print(component_tables(), end="")
