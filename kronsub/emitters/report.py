"""What every text emitter shows, as plain data: the derivation step by step.

Like the paper: the primitive metric and forces (16), (17), the connection
(19) and ``C`` (21), the projected metric (22), forces (23), velocity terms
(E), the energies (24) and the equations of motion (10').
"""
from __future__ import annotations

from typing import Callable

import sympy

from ..core.known_system import KnownSystem
from ..core.symbols import acceleration_symbol, velocity_symbol

Printer = Callable[[sympy.Expr], str]


def plain(expr) -> str:
    """sympy's ``str`` form: the JSON contract and the Markdown tables."""
    return sympy.sstr(expr, order="lex")


def latex_printer(coordinates) -> Printer:
    """LaTeX with velocities as dots: ``theta_dot`` -> ``\\dot{\\theta}``."""
    names = {}
    for q in coordinates:
        base = sympy.latex(q)
        names[velocity_symbol(q)] = rf"\dot{{{base}}}"
        names[acceleration_symbol(q)] = rf"\ddot{{{base}}}"

    def show(expr) -> str:
        return sympy.latex(expr, symbol_names=names, order="lex")

    return show


def matrix_rows(matrix: sympy.Matrix, show: Printer) -> list[list[str]]:
    return [[show(matrix[i, j]) for j in range(matrix.cols)] for i in range(matrix.rows)]


def build_report(system: KnownSystem, show: Printer) -> dict:
    """The derivation as nested lists of printed strings, in a fixed order."""
    tr = system.transition
    report = {
        "name": system.name,
        "description": system.description.strip(),
        "coordinates": [show(q) for q in system.coordinates],
        "coordinate_names": [q.name for q in system.coordinates],
        "parameters": [
            {"name": p.name, "symbol": show(p.symbol), "value": "" if p.value is None else show(p.value),
             "unit": p.unit, "description": p.description}
            for p in system.parameters
        ],
        "mass_matrix": matrix_rows(system.mass_matrix, show),
        "velocity_terms": [show(e) for e in system.velocity_terms],
        "forces": [show(e) for e in system.forces],
        "effects": [{"name": k, "forces": [show(e) for e in f]} for k, f in system.effect_forces.items()],
        "kinetic_energy": show(system.kinetic_energy),
        "potential_energy": show(system.potential_energy),
        "equations": [],
    }
    for eq in system.equations():
        report["equations"].append({"lhs": show(eq.lhs), "rhs": show(eq.rhs)})
    if tr is not None:
        prim_coords = list(tr.primitive_coordinates)
        report["primitive"] = {
            "parts": [{"name": n, "type": t or "known system"} for n, t in tr.parts],
            "coordinates": [show(x) for x in prim_coords],
            "metric": matrix_rows(tr.primitive_metric, show),
            "velocity_terms": [show(e) for e in tr.primitive_velocity_terms],
            "forces": [{"name": k, "forces": [show(e) for e in f]} for k, f in tr.primitive_forces.items()],
            "connection": [{"coordinate": show(x), "expression": show(e)} for x, e in tr.connection],
            "transformation": matrix_rows(tr.transformation, show),
        }
    return report
