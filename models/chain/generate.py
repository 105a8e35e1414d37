"""Write the n-link uniform-rod chain model: rods pinned in a chain from a fixed pivot.

Rod i has mass m<i>, length l<i>, centre (x<i>, y<i>) and axis angle a<i>; the
generalized coordinates q<i> are the rods' angles from the downward vertical.

    python models/chain/generate.py 5 > models/chain/chain5.yaml
"""
from __future__ import annotations

import sys


def chain_yaml(n: int) -> str:
    """The YAML text of the n-link chain model."""
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
    lines.append("initial: {" + ", ".join(f"q{i}: 0.1" for i in range(1, n + 1)) + "}")
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    sys.stdout.write(chain_yaml(int(sys.argv[1]) if len(sys.argv) > 1 else 5))
