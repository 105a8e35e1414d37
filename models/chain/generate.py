"""Write the n-link uniform-rod chain model: rods pinned in a chain from a fixed pivot.

Rod i has mass m<i>, length l<i>, centre (x<i>, y<i>) and axis angle a<i>; the
generalized coordinates q<i> are the rods' angles from the downward vertical.
With ``--hinges`` every hinge also has a torsional spring (stiffness k) and a
torsional damper (coefficient c), and the model has the scenes ``full`` (every
effect) and ``gravity_only``.

    python models/chain/generate.py 5 > models/chain/chain5.yaml
    python models/chain/generate.py 10 --hinges > chain10_hinges.yaml
"""
from __future__ import annotations

import sys


def chain_yaml(n: int, hinges: bool = False) -> str:
    """The YAML text of the n-link chain model (``hinges``: a spring and a damper at every hinge)."""
    if n < 1:
        raise ValueError("a chain needs at least one link")
    lines = [
        f"name: {n}-link rod chain",
        "description: >",
        f"  {n} uniform rods pinned in a chain from a fixed pivot at the origin, under",
        "  gravity; q<i> is the angle of rod i from the downward vertical.",
        "parameters:",
        "  g: {value: 9.81, unit: m/s^2}",
    ]
    if hinges:
        lines.append("  k: {value: 2, unit: N m/rad, description: stiffness of every hinge}")
        lines.append("  c: {value: 0.1, unit: N m s/rad, description: damping of every hinge}")
    for i in range(1, n + 1):
        lines.append(f"  m{i}: {{value: 1, unit: kg}}")
        lines.append(f"  l{i}: {{value: 1, unit: m}}")
    lines.append("components:")
    for i in range(1, n + 1):
        lines.append(f"  rod{i}: {{type: rod, parameters: {{mass: m{i}, length: l{i}}}, "
                     f"coordinates: {{x: x{i}, y: y{i}, angle: a{i}}}}}")
    lines.append("coordinates: [" + ", ".join(f"q{i}" for i in range(1, n + 1)) + "]")
    lines.append("connection:")
    for i in range(1, n + 1):
        above_x = "".join(f"l{j}*sin(q{j}) + " for j in range(1, i))
        above_y = "".join(f" - l{j}*cos(q{j})" for j in range(1, i))
        lines.append(f"  x{i}: {above_x}l{i}/2*sin(q{i})")
        lines.append(f"  y{i}:{above_y} - l{i}/2*cos(q{i})".replace(":  - ", ": -").replace(": - ", ": -"))
        lines.append(f"  a{i}: q{i} - pi/2")
    lines.append("effects:")
    lines.append("  gravity: {type: gravity, g: g, direction: [0, -1]}")
    if hinges:
        for i in range(1, n + 1):
            angle = f"a{i} - a{i - 1}" if i > 1 else "a1 + pi/2"
            lines.append(f"  spring{i}: {{type: torsional_spring, angle: {angle}, stiffness: k}}")
            lines.append(f"  damper{i}: {{type: torsional_damper, angle: {angle}, coefficient: c}}")
    lines.append("initial: {" + ", ".join(f"q{i}: 0.1" for i in range(1, n + 1)) + "}")
    if hinges:
        lines.append("scenes:")
        lines.append("  full: {description: gravity and every hinge's spring and damper}")
        lines.append("  gravity_only: {description: the hinges turn freely, effects: [gravity]}")
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    args = [a for a in sys.argv[1:] if a != "--hinges"]
    sys.stdout.write(chain_yaml(int(args[0]) if args else 5, hinges="--hinges" in sys.argv[1:]))
