"""Starter models for ``kronsub new``: small models that derive, to be edited.

Each starter is YAML text with the model's name put in by :func:`starter` (through
the YAML dumper, so any name is a safe scalar).
"""
from __future__ import annotations

import yaml

PENDULUM = """\
description: >
  A uniform rod pinned at one end (a compound pendulum), driven by a torque tau.
  theta is the rod's angle from the downward vertical.
parameters:
  m: {value: 1, unit: kg, description: mass of the rod}
  L: {value: 1, unit: m, description: length of the rod}
  g: {value: 9.81, unit: m/s^2}
  tau: {value: 0, unit: N m, description: torque driving the rod}
components:
  rod: {type: pinned_rod, parameters: {mass: m, length: L}, coordinates: [theta]}
coordinates: [theta]
effects:
  gravity: {type: gravity, g: g}
  drive: {type: torque, component: rod, value: tau}
initial: {theta: 0.5}
"""

CART_POLE = """\
description: >
  A cart on the x axis with a uniform pole pinned at its centre, pushed by a force F.
  theta is the pole's angle from the downward vertical.
parameters:
  mc: {value: 1, unit: kg, description: mass of the cart}
  mp: {value: 0.1, unit: kg, description: mass of the pole}
  l: {value: 1, unit: m, description: length of the pole}
  g: {value: 9.81, unit: m/s^2}
  F: {value: 0, unit: N, description: force pushing the cart}
components:
  cart: {type: particle1d, parameters: {mass: mc}, coordinates: [x]}
  pole: {type: rod, parameters: {mass: mp, length: l}, coordinates: {x: pole_x, y: pole_y, angle: pole_angle}}
coordinates: [x, theta]
connection:
  pole_x: x + l/2*sin(theta)
  pole_y: -l/2*cos(theta)
  pole_angle: theta - pi/2
effects:
  gravity: {type: gravity, g: g, direction: [0, -1], components: [pole]}
  push: {type: force, point: cart.centre, vector: [F]}
initial: {theta: 3.0}
"""

DOUBLE_PENDULUM = """\
description: >
  Two point masses on massless rods; q1, q2 are the rods' angles from the downward vertical.
parameters:
  m1: {value: 1, unit: kg}
  m2: {value: 1, unit: kg}
  l1: {value: 1, unit: m}
  l2: {value: 1, unit: m}
  g: {value: 9.81, unit: m/s^2}
components:
  bob1: {type: particle2d, parameters: {mass: m1}, coordinates: [x1, y1]}
  bob2: {type: particle2d, parameters: {mass: m2}, coordinates: [x2, y2]}
coordinates: [q1, q2]
connection:
  x1: l1*sin(q1)
  y1: -l1*cos(q1)
  x2: l1*sin(q1) + l2*sin(q2)
  y2: -l1*cos(q1) - l2*cos(q2)
effects:
  gravity: {type: gravity, g: g, direction: [0, -1]}
initial: {q1: 2*pi/3, q2: -pi/18}
"""

SPRING_MASS = """\
description: >
  A mass on a line tied to a wall at x = 0 by a spring and a damper, pushed by a force F.
parameters:
  m: {value: 1, unit: kg}
  k: {value: 10, unit: N/m, description: spring stiffness}
  c: {value: 0.2, unit: N s/m, description: damping coefficient}
  F: {value: 0, unit: N}
components:
  block: {type: particle1d, parameters: {mass: m}, coordinates: [x]}
coordinates: [x]
effects:
  spring: {type: spring, between: [block.centre, [0]], stiffness: k}
  damper: {type: damper, between: [block.centre, [0]], coefficient: c}
  push: {type: force, point: block.centre, vector: [F]}
initial: {x: 0.1}
"""


def chain(links: int) -> str:
    """``links`` uniform rods pinned end to end from a fixed pivot; q<i> from the vertical."""
    lines = ["description: >",
             f"  {links} uniform rods pinned in a chain from a fixed pivot at the origin, under gravity;",
             "  q<i> is the angle of rod i from the downward vertical.",
             "parameters:", "  g: {value: 9.81, unit: m/s^2}"]
    for i in range(1, links + 1):
        lines += [f"  m{i}: {{value: 1, unit: kg}}", f"  l{i}: {{value: 1, unit: m}}"]
    lines.append("components:")
    for i in range(1, links + 1):
        lines.append(f"  rod{i}: {{type: rod, parameters: {{mass: m{i}, length: l{i}}}, "
                     f"coordinates: {{x: x{i}, y: y{i}, angle: a{i}}}}}")
    lines.append("coordinates: [" + ", ".join(f"q{i}" for i in range(1, links + 1)) + "]")
    lines.append("connection:")
    for i in range(1, links + 1):
        x = " + ".join([f"l{j}*sin(q{j})" for j in range(1, i)] + [f"l{i}/2*sin(q{i})"])
        y = " - ".join([f"-l{j}*cos(q{j})" if j == 1 else f"l{j}*cos(q{j})" for j in range(1, i)]
                       + [f"l{i}/2*cos(q{i})" if i > 1 else f"-l{i}/2*cos(q{i})"])
        lines += [f"  x{i}: {x}", f"  y{i}: {y}", f"  a{i}: q{i} - pi/2"]
    lines += ["effects:", "  gravity: {type: gravity, g: g, direction: [0, -1]}",
              "initial: {" + ", ".join(f"q{i}: 0.1" for i in range(1, links + 1)) + "}"]
    return "\n".join(lines) + "\n"


STARTERS = {
    "pendulum": lambda links: PENDULUM,
    "cart_pole": lambda links: CART_POLE,
    "double_pendulum": lambda links: DOUBLE_PENDULUM,
    "spring_mass": lambda links: SPRING_MASS,
    "chain": chain,
}


def starter(kind: str, name: str, links: int = 3) -> str:
    """The YAML text of starter ``kind`` named ``name``."""
    head = yaml.safe_dump({"name": name}, allow_unicode=True, default_flow_style=False, width=10**6)
    return head + STARTERS[kind](links)


__all__ = ["CART_POLE", "DOUBLE_PENDULUM", "PENDULUM", "SPRING_MASS", "STARTERS", "chain", "starter"]
