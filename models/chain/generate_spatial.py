"""Write the n-body spatial chain model: rigid rods hung one below the other on ball joints.

Body i is a uniform rod (a cylinder of mass m<i>, length l<i>, radius r) in space, its
orientation given by X-Y-Z Euler angles a<i>, b<i>, c<i> (the generalized coordinates), its
centre (x<i>, y<i>, z<i>) set by the joints: the top of rod 1 is held at the origin, the top
of rod i at the bottom of rod i-1. The joints are the connection: the centre of rod i is
``-sum_{j<i} l<j> e<j> - l<i>/2 e<i>``, ``e = (sin b, -sin a cos b, cos a cos b)`` a rod's axis
(the third column of ``Rx(a) Ry(b) Rz(c)``); with ``--pins`` they are ``pin`` constraints
instead (three equations each, solved as a closed loop is). Gravity along -z; at rest the
rods hang straight down, clear of the Euler angles' singularity.

    python models/chain/generate_spatial.py 3 > spatial3.yaml
    python models/chain/generate_spatial.py 3 --pins > spatial3_pins.yaml
"""
from __future__ import annotations

import sys


def _centre(i: int, k: int) -> str:
    """Component ``k`` (x, y, z) of the centre of rod i: ``-sum_{j<i} l<j> e<j> - l<i>/2 e<i>``,
    the axis ``e = (sin b, -sin a cos b, cos a cos b)`` written with its sign."""
    sign, axis = (("-", "sin(b{})"), ("+", "sin(a{0})*cos(b{0})"), ("-", "cos(a{0})*cos(b{0})"))[k]
    terms = [f"l{j}*{axis.format(j)}" for j in range(1, i)] + [f"l{i}/2*{axis.format(i)}"]
    text = f" {sign} ".join(terms)
    return f"-{text}" if sign == "-" else text


def spatial_chain_yaml(n: int, pins: bool = False) -> str:
    """The YAML text of the n-body spatial chain on ball joints (``pins``: the joints as
    ``pin`` constraints, not as the connection)."""
    if n < 1:
        raise ValueError("a chain needs at least one body")
    lines = [
        f"name: {n}-body spatial chain",
        "description: >",
        f"  {n} uniform rods hung one below the other on ball joints from a fixed point at",
        "  the origin, under gravity; a<i>, b<i>, c<i> are the X-Y-Z Euler angles of rod i.",
        "parameters:",
        "  g: {value: 9.81, unit: m/s^2}",
        "  r: {value: 0.05, unit: m, description: radius of every rod}",
    ]
    for i in range(1, n + 1):
        lines.append(f"  m{i}: {{value: 1, unit: kg}}")
        lines.append(f"  l{i}: {{value: 1, unit: m}}")
    lines.append("components:")
    for i in range(1, n + 1):
        lines += [
            f"  rod{i}:",
            "    type: rigid_body3d",
            "    euler: XYZ",
            f"    parameters: {{mass: m{i}, Ixx: m{i}*(3*r**2 + l{i}**2)/12, Iyy: m{i}*(3*r**2 + l{i}**2)/12, "
            f"Izz: m{i}*r**2/2}}",
            f"    coordinates: [x{i}, y{i}, z{i}, a{i}, b{i}, c{i}]",
            f"    points: {{top: [0, 0, l{i}/2], bottom: [0, 0, -l{i}/2]}}",
        ]
    lines.append("coordinates: [" + ", ".join(f"a{i}, b{i}, c{i}" for i in range(1, n + 1)) + "]")
    if pins:
        lines.append("constraints:")
        lines.append("  joint1: {pin: [rod1.top, [0, 0, 0]]}")
        for i in range(2, n + 1):
            lines.append(f"  joint{i}: {{pin: [rod{i}.top, rod{i - 1}.bottom]}}")
    else:
        lines.append("connection:")
        for i in range(1, n + 1):
            for k, name in enumerate("xyz"):
                lines.append(f"  {name}{i}: {_centre(i, k)}")
    lines.append("effects:")
    lines.append("  gravity: {type: gravity, g: g}")
    initial = ", ".join(f"a{i}: 0.1, b{i}: {0.05 * i:g}" for i in range(1, n + 1))
    lines.append(f"initial: {{{initial}}}")
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    args = [a for a in sys.argv[1:] if a != "--pins"]
    sys.stdout.write(spatial_chain_yaml(int(args[0]) if args else 3, pins="--pins" in sys.argv[1:]))
