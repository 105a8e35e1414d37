"""What every text emitter shows, as plain data: the derivation step by step.

Like the paper: the primitive metric and forces (16), (17), the connection
(19) and ``C`` (21), the projected metric (22), forces (23), velocity terms
(E), the energies (24) and the equations of motion (10').
"""
from __future__ import annotations

from typing import Callable

import sympy
from markupsafe import Markup

from ..core.known_system import KnownSystem
from ..core.symbols import acceleration_symbol, velocity_symbol

Printer = Callable[[sympy.Expr], str]


def plain(expr) -> str:
    """sympy's ``str`` form: the JSON contract and the Markdown tables."""
    return sympy.sstr(expr, order="lex")


def latex_printer(coordinates, implicit=None) -> Printer:
    """LaTeX with velocities as dots: ``theta_dot`` -> ``\\dot{\\theta}``; with implicit constraints
    ``lambda_phi_theta`` -> ``\\lambda_{\\phi\\theta}`` and ``gamma_phi`` -> ``\\gamma_{\\phi}``."""
    names = {}
    if implicit is not None:
        for a, d in enumerate(implicit.dependent):
            for j, q in enumerate(implicit.independent):
                s = implicit.sensitivities[a, j]
                names[s] = r"\lambda" if s.name == "lambda" else rf"\lambda_{{{sympy.latex(d)}{sympy.latex(q)}}}"
            g = implicit.convective[a]
            names[g] = r"\gamma" if g.name == "gamma" else rf"\gamma_{{{sympy.latex(d)}}}"
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
            "forces": [{"name": k, "forces": [show(e) for e in f]} for k, f in tr.primitive_forces.items()
                       if k not in tr.direct_effects],
            "applied_in_subspace": list(tr.direct_effects),
            "connection": [{"coordinate": show(x), "expression": show(e)} for x, e in tr.connection],
            "transformation": matrix_rows(tr.transformation, show),
            "columns": [show(q) for q in _columns(system)],
        }
    if system.implicit is not None:
        report["implicit"] = implicit_report(system.implicit, show)
    return report


def _columns(system: KnownSystem):
    """The coordinates ``C`` of the connection maps to: ``y`` when constraints follow."""
    if system.implicit is not None:
        return system.implicit.intermediate
    return system.coordinates


def implicit_report(imp, show: Printer) -> dict:
    """The constraints (25) and the "where" block of the named intermediates (26)-(29)."""
    closed = dict(imp.closed_form)
    branch = dict(imp.branch)
    defined = dict(imp.definitions)
    deps = []
    for d in imp.dependent:
        deps.append({"name": show(d), "plain": d.name,
                     "closed_form": show(closed[d]) if d in closed else "",
                     "branch": Markup(repr(branch[d])) if d in branch else ""})
    lams = []
    for a, d in enumerate(imp.dependent):
        for j, q in enumerate(imp.independent):
            s = imp.sensitivities[a, j]
            lams.append({"name": show(s), "plain": s.name, "of": Markup(d.name), "by": Markup(q.name),
                         "definition": show(defined[s]) if s in defined else ""})
    gammas = []
    for a, d in enumerate(imp.dependent):
        s = imp.convective[a]
        gammas.append({"name": show(s), "plain": s.name, "of": Markup(d.name),
                       "definition": show(defined[s]) if s in defined else "",
                       "quadratic": show(imp.quadratic[a])})
    return {
        "choice": imp.choice,
        "independent": [show(q) for q in imp.independent],
        "independent_names": [q.name for q in imp.independent],
        "dependent": deps,
        # names are validated identifiers; the source is free text, escaped by each template
        "constraints": [{"name": Markup(c.name), "expression": show(c.expression), "source": c.source}
                        for c in imp.constraints],
        "jacobian_dependent": matrix_rows(imp.jacobian_dependent, show),
        "jacobian_independent": matrix_rows(imp.jacobian_independent, show),
        "sensitivities": lams,
        "convective": gammas,
    }
