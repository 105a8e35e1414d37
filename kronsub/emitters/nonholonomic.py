"""What the text emitters show of a system under velocity constraints (:mod:`..core.nonholonomic`):
the constraints ``A xdot + b = 0``, the speeds, the kinematic equations ``xdot = C u + d`` and
``Mbar udot + hbar = fbar`` in the speeds, (9'), (D)-(F) with ``Cdot`` along the motion."""
from __future__ import annotations

import sympy

from ..core.known_system import KnownSystem, SpeedEquations
from ..core.nonholonomic import frame_entry, speed_rates
from ..core.simplify import tidy
from ..core.symbols import velocity_symbol
from .report import Printer, matrix_rows


def speeds_report(system: KnownSystem, show: Printer) -> dict:
    """The equations in the speeds as printed strings, in a fixed order."""
    s: SpeedEquations = system.speeds
    x = system.coordinates
    rates = speed_rates(s.speeds, x)
    p = len(s.speeds)
    mass = s.mass_matrix.applyfunc(tidy)
    hbar = [tidy(e) for e in s.velocity_terms]
    # in a change of velocity frame the effects' fbar simplify together (Park's three phases)
    fbar = [tidy(frame_entry(e) if not s.constraint_names else e) for e in s.forces]
    lhs = [sympy.Add(*[mass[i, j] * rates[j] for j in range(p)], hbar[i]) for i in range(p)]
    velocities = [velocity_symbol(q) for q in x]
    constraints = [sympy.Add(*[s.constraint_matrix[i, j] * velocities[j] for j in range(len(x))],
                             s.constraint_offset[i]) for i in range(len(s.constraint_names))]
    return {
        "speeds": [show(u) for u in s.speeds],
        "speed_names": [u.name for u in s.speeds],
        "rates": [show(r) for r in rates],
        "rate_names": [r.name for r in rates],
        "definitions": [{"speed": show(u), "name": u.name, "expression": show(e)} for u, e in s.definitions],
        "constraints": [{"name": name, "expression": show(tidy(e))}
                        for name, e in zip(s.constraint_names, constraints)],
        "constraint_matrix": matrix_rows(s.constraint_matrix, show),
        "constraint_offset": [show(e) for e in s.constraint_offset],
        "transformation": matrix_rows(s.transformation, show),
        "offset": [show(e) for e in s.offset],
        "kinematics": [{"velocity": show(v), "name": v.name, "expression": show(tidy(e))}
                       for v, e in zip(velocities, s.kinematics)],
        "mass_matrix": matrix_rows(mass, show),
        "velocity_terms": [show(e) for e in hbar],
        "forces": [show(e) for e in fbar],
        "effects": [{"name": k, "forces": [show(tidy(e)) for e in f]} for k, f in s.effect_forces.items()],
        "kinetic_energy": show(s.kinetic_energy),
        "equations": [{"lhs": show(lhs[i]), "rhs": show(fbar[i])} for i in range(p)],
        "holonomic": [{"name": c.name, "expression": show(tidy(c.expression))} for c in s.holonomic],
        "dependent": [show(q) for q in s.dependent],
    }


__all__ = ["speeds_report"]
