"""The equations in the speeds in Kron's implicit form: the pieces and the projection, not expanded.

Under velocity constraints whose projection onto the speeds is made in numbers
(:func:`~kronsub.core.projection_work.projected_in_numbers`) the printed report gives what the
equations are made of, exactly: the primitive's metric ``M_p``, velocity terms ``h_p`` and
forces (16), (17), the connection ``x_p = x_p(x)`` (19) and its ``J = dx_p/dx`` (21), the forces
``f = J^T f_p`` (8'), (23) in the coordinates ``x``, the velocity constraints' rows
``A(x) xdot + b(x, t)`` as made, the configuration constraints ``g(x, t) = 0`` and the speeds
``u = Y xdot``, and the projection written out:

    M = J^T M_p J  (9'),   h = J^T (M_p Jdot xdot + h_p)  (E)
    [A; Y] C = [0; I],   [A; Y] d = [-b; 0],   xdot = C u + d
    Mbar = C^T M C  (9'), (D),   hbar = C^T (M (Cdot u + ddot) + h)  (E),   fbar = C^T f  (8'), (F)

A system without a primitive to take ``M`` from (no transition) prints ``M``, ``h`` in ``x`` as
derived. ``--reactions`` gives the multipliers' defining equation in the same form:
``M xddot + h = f + A^T mu``, ``A A^T mu = A (M xddot + h - f)``.
"""
from __future__ import annotations

import json

import sympy

from ..core.known_system import KnownSystem
from ..core.nonholonomic import speed_rates
from ..core.nonholonomic_linearize import primitive_metric, velocity_rows
from ..core.projection_work import NUMERIC_FROM, projected_in_numbers, projection_work
from ..core.simplify import recompact, tidy
from ..core.symbols import velocity_symbol
from .escape import json_document, latex_text
from .report import Printer, build_report, primitive_report, report_head

FORM = "implicit"
"""The value of the JSON field ``speeds_form`` of a system printed in this form."""

EVALUATION = ("S = [A; Y] with A, b of the velocity_constraints (A = d row/d velocity, b = row at zero velocities), "
              "then of the configuration_constraints' rates (G = dg/dx, dg/dt), Y of speed_definitions; "
              "S C = [0; I], S d = [-b; 0], velocities = C * [speeds] + d; "
              "{metric}; "
              "mass_matrix = C^T M C, velocity_terms = C^T (M (Cdot u + ddot) + h) with Cdot u + ddot = "
              "d(C u + d)/dx_k * velocities_k + d(C u + d)/dt (speeds held), forces = C^T f, f = unconstrained.forces, "
              "each at velocities = C u + d")
PRIMITIVE = ("M = J^T W J and h = J^T (W Jdot velocities + h_p) with W = primitive.metric and h_p = "
             "primitive.velocity_terms at primitive.connection (primitive velocities = J velocities), "
             "J = primitive.transformation, Jdot = dJ/dx_k * velocities_k")
COORDINATES = "M = unconstrained.mass_matrix, h = unconstrained.velocity_terms"


def implicit_form(system: KnownSystem) -> bool:
    """Whether ``system`` is printed in the implicit form: its projection onto the speeds is made
    in numbers (the one criterion of :mod:`~kronsub.core.projection_work`)."""
    return system.speeds is not None and projected_in_numbers(system)


def from_primitive(system: KnownSystem) -> bool:
    """Whether ``M`` and ``h`` in the coordinates are written through the primitive
    (:func:`~kronsub.core.nonholonomic_linearize.primitive_metric`), not formed."""
    return primitive_metric(system) is not None


def printed_names(system: KnownSystem) -> frozenset[str]:
    """The names the printed pieces use (the model's own, for the printers), found without
    forming ``M`` in the coordinates."""
    names = {p.name for p in system.parameters} | {q.name for q in (*system.coordinates, *system.velocities)}
    names.update(system.currents.values())
    exprs = [*system.forces, sympy.sympify(system.potential_energy), *_rows(system),
             *(c.expression for c in system.speeds.holonomic), *(e for _, e in system.speeds.definitions)]
    tr = system.transition
    if from_primitive(system):
        exprs += [*tr.primitive_metric, *tr.primitive_velocity_terms, *(e for _, e in tr.connection)]
    else:
        exprs += [*system.mass_matrix, *system.velocity_terms]
    for e in exprs:
        names.update(s.name for s in sympy.sympify(e).free_symbols)
    return frozenset(names)


def _rows(system: KnownSystem) -> list[sympy.Expr]:
    """The velocity constraints ``A xdot + b`` as made (a contact's rows, not reduced), without
    the configuration constraints' rates (:func:`~kronsub.core.nonholonomic_linearize.velocity_rows`)."""
    return [sympy.sympify(r) for r in velocity_rows(system)]


def implicit_report(system: KnownSystem, show: Printer, named: bool = True) -> dict:
    """The report of ``system`` in the implicit form, as printed strings in a fixed order: the
    keys of :func:`~.report.build_report` (``named`` as there) less ``Mbar``, ``hbar``, ``T`` in
    the coordinates when they come from the primitive (``unformed``), and ``speeds`` with the
    pieces of the projection."""
    s = system.speeds
    if from_primitive(system):
        effects = list(system.effect_forces.items())
        forces = [recompact(f, system.coordinates) if sum(e[i] != 0 for _, e in effects) > 1 else tidy(f)
                  for i, f in enumerate(system.forces)]
        r = {
            **report_head(system, show),
            "forces": [show(e) for e in forces],
            "effects": [{"name": k, "forces": [show(e) for e in f]} for k, f in effects],
            "potential_energy": show(system.potential_energy),
            "where": [],
            "primitive": primitive_report(system, show),
            "unformed": True,
        }
    else:
        r = build_report(system, show, named=named)
    rates = speed_rates(s.speeds, system.coordinates)
    rows = _rows(system)
    r["speeds"] = {
        "implicit": True,
        "work": projection_work(system),
        "numeric_from": NUMERIC_FROM,
        "metric": "primitive" if from_primitive(system) else "coordinates",
        "speeds": [show(u) for u in s.speeds],
        "speed_names": [u.name for u in s.speeds],
        "rates": [show(a) for a in rates],
        "rate_names": [a.name for a in rates],
        "definitions": [{"speed": show(u), "name": u.name, "expression": show(e)} for u, e in s.definitions],
        "constraints": [{"name": name, "expression": show(e)} for name, e in zip(s.constraint_names, rows)],
        "holonomic": [{"name": c.name, "expression": show(c.expression)} for c in s.holonomic],
        "dependent": [show(q) for q in s.dependent],
        "velocities": [show(velocity_symbol(q)) for q in system.coordinates],
    }
    return r


def implicit_json(r: dict, data: dict) -> dict:
    """The JSON contract of the implicit form: ``data`` (name, coordinates, parameters, the
    primitive) with the pieces of ``r`` (:func:`implicit_report`, printed plain) and
    ``speeds_form: implicit``; the equations' evaluation spelt out under ``projection``."""
    s = r["speeds"]
    primitive = s["metric"] == "primitive"
    unconstrained = {"forces": r["forces"], "effects": {e["name"]: e["forces"] for e in r["effects"]}}
    if not primitive:
        unconstrained.update(mass_matrix=r["mass_matrix"], velocity_terms=r["velocity_terms"],
                             kinetic_energy=r["kinetic_energy"])
    out = {k: v for k, v in data.items() if k in ("name", "coordinates", "velocities", "parameters", "currents",
                                                   "primitive", "implicit")}
    out.update({
        "speeds_form": FORM,
        "speeds": s["speed_names"],
        "speed_rates": s["rate_names"],
        "speed_definitions": {d["name"]: d["expression"] for d in s["definitions"]},
        "velocity_constraints": {c["name"]: c["expression"] for c in s["constraints"]},
        **({"configuration_constraints": {c["name"]: c["expression"] for c in s["holonomic"]},
            "dependent": s["dependent"]} if s["holonomic"] else {}),
        "potential_energy": r["potential_energy"],
        "projection": {
            "work": s["work"],
            "numeric_from": s["numeric_from"],
            "metric_from": s["metric"],
            "evaluation": EVALUATION.format(metric=PRIMITIVE if primitive else COORDINATES),
        },
        "equation_form": "mass_matrix * [speed_rates] + velocity_terms = forces; [velocities] = C * [speeds] + d; "
                         "neither expanded: both formed at a state as projection.evaluation says",
        "unconstrained": unconstrained,
    })
    return out


MULTIPLIER_EQUATION = "A A^T mu = A (M xddot + h - f), xddot = C udot + Cdot u + ddot"
"""The multipliers' defining equation in the implicit form (plain text, the JSON's and Markdown's)."""

MULTIPLIERS = ("`mu_<constraint>` are the multipliers of the velocity constraints (then of the configuration "
               "constraints' rates), `M xddot + h = f + A^T mu` in the coordinates x, written as their defining "
               "equation, not expanded: `A A^T mu = A (M xddot + h - f)` with `xddot = C udot + Cdot u + ddot`, "
               "`udot` from the equations in the speeds, `A`, `C`, `d`, `M`, `h`, `f` as in the equations in the "
               "speeds above (the projection work is too large to form them symbolically). For a constraint that a "
               "contact point's velocity vanish along a direction, its multiplier is the contact force along it.")


def multiplier_names(system: KnownSystem) -> list[str]:
    """``mu_<constraint>`` per velocity constraint (the configuration constraints' last)."""
    return [f"mu_{name}" for name in system.speeds.constraint_names]


def with_multipliers(text: str, system: KnownSystem, fmt: str) -> str:
    """The derivation ``text`` in ``fmt`` with the multipliers of the constraints (viewpoint
    (alpha)) given by their defining equation, ``M xddot + h = f + A^T mu``, in the implicit form:
    ``A`` has full row rank, so ``A A^T mu = A (M xddot + h - f)`` holds them exactly."""
    names = multiplier_names(system)
    if fmt == "json":
        data = json.loads(text)
        data["reactions"] = {"implicit": {"unknowns": names, "equation": MULTIPLIER_EQUATION},
                             "note": MULTIPLIERS.replace("`", "")}
        return json_document(data, indent=2) + "\n"
    if fmt == "latex":
        unknowns = " \\\\ ".join(rf"\mu_{{\mathrm{{{latex_text(n[3:])}}}}}" for n in names)
        section = ("\\section*{Reactions}\n" + latex_text(MULTIPLIERS.replace("`", "")) + "\n\\begin{align*}\n"
                   + rf"A A^{{\mathsf{{T}}}} \begin{{bmatrix}} {unknowns} \end{{bmatrix}} &= A (M \ddot{{x}} + h - f),"
                   + r" \quad \ddot{x} = C \dot{u} + \dot{C} u + \dot{d}" + "\n\\end{align*}\n")
        return text.replace("\\end{document}", section + "\\end{document}")
    lines = ["", "## Reactions (viewpoint (alpha))", "", MULTIPLIERS, "",
             f"- `A A^T [{', '.join(names)}] = A (M xddot + h - f)`, `xddot = C udot + Cdot u + ddot`"]
    return text.rstrip("\n") + "\n" + "\n".join(lines) + "\n"


__all__ = ["COORDINATES", "EVALUATION", "FORM", "MULTIPLIERS", "PRIMITIVE", "from_primitive", "implicit_form",
           "implicit_json", "implicit_report", "MULTIPLIER_EQUATION", "multiplier_names", "printed_names", "with_multipliers"]
