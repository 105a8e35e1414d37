"""Markdown, LaTeX and JSON emitters of a derived system (the ``--format`` registry)."""
from __future__ import annotations

from importlib import resources

import jinja2

from ..collector import collector_paused
from ..core.known_system import KnownSystem
from .escape import Markup, environment, json_document
from .implicit_speeds import implicit_form, implicit_json, implicit_report, printed_names
from .latex_layout import WIDTH, lines, measure, unbroken
from .nonholonomic import speeds_report
from .report import ModelStrPrinter, build_report, latex_printer, model_names, plain_printer


def template_environment() -> jinja2.Environment:
    """The templates' environment: free text reaches them only through an escaping filter."""
    loader = jinja2.FunctionLoader(lambda name: resources.files("kronsub.templates").joinpath(name).read_text("utf-8"))
    return environment(loader)


def _fits(rows) -> bool:
    """Whether a matrix (rows of cells) or a column (cells) fits the page whole."""
    rows = [[cell] if isinstance(cell, str) else list(cell) for cell in rows]
    if not rows:
        return True
    columns = max(len(row) for row in rows)
    widths = [max((measure(row[j]) for row in rows if j < len(row)), default=0.0) for j in range(columns)]
    return sum(widths) + 1.5 * columns <= WIDTH


def _broken(text) -> Markup:
    """A formula over as many lines as it needs, continued with ``&\\quad`` in an ``align*``."""
    return Markup(" \\\\\n&\\quad ".join(lines(text)))


_SYMBOLS = {"M": "M", "C": "C", "h": "h", "f": "f", "Mbar": r"\bar{M}", "fbar": r"\bar{f}", "hbar": r"\bar{h}"}


def _symbol(name: str) -> Markup:
    """The LaTeX of one of the paper's matrices, named in the template (``Mbar`` -> ``\\bar{M}``)."""
    return Markup(_SYMBOLS[name])


def _trusted(show):
    """Expressions printed by sympy (of validated names) are output as they are."""
    return lambda expr: Markup(show(expr))


@collector_paused()  # see kronsub.collector
def emit_markdown(system: KnownSystem) -> str:
    """Markdown: the derivation step by step, expressions in sympy's ``str`` form."""
    names = _names(system)
    printer = ModelStrPrinter(names, system.printed_names)
    r = _report(system, _trusted(printer.doprint), names, lambda products, others: Markup(
        printer.sum_of_products(products, others)))
    return template_environment().get_template("derive.md.j2").render(r=r)


@collector_paused()  # see kronsub.collector
def emit_latex(system: KnownSystem) -> str:
    """A standalone LaTeX document of the derivation."""
    show = latex_printer(tuple(system.coordinates) + tuple(
        system.transition.primitive_coordinates if system.transition else ()) + tuple(
        system.speeds.speeds if system.speeds is not None else ()), system.implicit, breaks=True,
        currents=system.currents)
    env = template_environment()
    env.filters["fits"] = _fits
    env.filters["broken"] = _broken
    env.filters["symbol"] = _symbol
    return unbroken(env.get_template("derive.tex.j2").render(r=_report(system, _trusted(show))))


def _names(system: KnownSystem) -> frozenset[str]:
    """The model's own names, for the printers (without forming what the implicit form leaves unformed)."""
    return printed_names(system) if implicit_form(system) else model_names(system)


def _report(system: KnownSystem, show, names: frozenset[str] | None = None, sums=None) -> dict:
    """The report, with the equations in the speeds under velocity constraints (in the implicit
    form when their projection is made in numbers, :mod:`.implicit_speeds`); ``names``: the
    model's, as `_names` gives them, when the caller has them; ``sums``: the printer's sums of
    products (:func:`.report.build_report`)."""
    if implicit_form(system):
        return implicit_report(system, show)
    r = build_report(system, show, names=names, sums=sums)
    if system.speeds is not None:
        r["speeds"] = speeds_report(system, show)
    return r


@collector_paused()  # see kronsub.collector
def emit_json(system: KnownSystem) -> str:
    """The machine contract: ``Mbar qddot + hbar = fbar`` with sympy ``str`` expressions (in the
    speeds, in the implicit form when their projection is made in numbers: ``speeds_form``)."""
    implicit = implicit_form(system)
    printer = ModelStrPrinter(_names(system), system.printed_names)
    show = printer.doprint
    r = implicit_report(system, show, named=False) if implicit else build_report(
        system, show, named=False, sums=printer.sum_of_products)
    data = {
        "name": r["name"],
        "coordinates": r["coordinate_names"],
        "velocities": [system.name_of(v) for v in system.velocities],
        "parameters": {p["name"]: {"value": p["value"] or None, "unit": p["unit"], "description": p["description"]}
                       for p in r["parameters"]},
        **({} if r.get("unformed") else {"mass_matrix": r["mass_matrix"]}),
        **({} if r.get("unformed") else {"velocity_terms": r["velocity_terms"]}),
        "forces": r["forces"],
        "effects": {e["name"]: e["forces"] for e in r["effects"]},
        **({} if r.get("unformed") else {"kinetic_energy": r["kinetic_energy"]}),
        "potential_energy": r["potential_energy"],
        "equation_form": "mass_matrix * [coordinate_ddot] + velocity_terms = forces",
    }
    if system.currents:  # a charge's velocity is printed as its current, its acceleration as the current's rate
        data["currents"] = dict(system.currents)
    if "primitive" in r:
        p = r["primitive"]
        data["primitive"] = {
            "coordinates": p["coordinates"],
            "metric": p["metric"],
            "velocity_terms": p["velocity_terms"],
            "forces": {f["name"]: f["forces"] for f in p["forces"]},
            "connection": {c["coordinate"]: c["expression"] for c in p["connection"]},
            "transformation": p["transformation"],
        }
        if "drive" in p:  # x = x(xbar, t): the velocity terms hold the drive's; T + V is not conserved
            data["primitive"]["drive"] = {
                "velocity": dict(zip(data["primitive"]["coordinates"], p["drive"]["velocity"])),
                "velocity_terms": p["drive"]["velocity_terms"],
                "energy_conserved": False,
            }
    if "implicit" in r:
        data["implicit"] = _implicit_json(r["implicit"])
    if implicit:
        data = implicit_json(r, data)
    elif system.speeds is not None:
        data = _speeds_json(data, speeds_report(system, plain_printer(model_names(system), system.printed_names)))
    return json_document(data, indent=2) + "\n"


def _speeds_json(data: dict, s: dict) -> dict:
    """Under velocity constraints the contract is the equations in the speeds ``u`` with the
    kinematic equations ``xdot = C u + d``; the system in ``x`` before the constraints is kept
    under ``unconstrained``."""
    unconstrained = {k: data[k] for k in ("mass_matrix", "velocity_terms", "forces", "effects", "kinetic_energy")}
    out = {k: v for k, v in data.items() if k not in unconstrained and k != "equation_form"}
    out.update({
        "speeds": s["speed_names"],
        "speed_rates": s["rate_names"],
        "speed_definitions": {d["name"]: d["expression"] for d in s["definitions"]},
        "velocity_constraints": {c["name"]: c["expression"] for c in s["constraints"]},
        "constraint_matrix": s["constraint_matrix"],
        "constraint_offset": s["constraint_offset"],
        "transformation": s["transformation"],
        "offset": s["offset"],
        "kinematics": {k["name"]: k["expression"] for k in s["kinematics"]},
        "mass_matrix": s["mass_matrix"],
        "velocity_terms": s["velocity_terms"],
        "forces": s["forces"],
        "effects": {e["name"]: e["forces"] for e in s["effects"]},
        "kinetic_energy": s["kinetic_energy"],
        "potential_energy": data["potential_energy"],
        "equation_form": "mass_matrix * [speed_rates] + velocity_terms = forces; [velocities] = kinematics "
                         "(= transformation * [speeds] + offset), constraint_matrix * [velocities] + "
                         "constraint_offset = 0",
        **({"configuration_constraints": {c["name"]: c["expression"] for c in s["holonomic"]},
            "dependent": s["dependent"]} if s["holonomic"] else {}),
        "unconstrained": unconstrained,
    })
    return out


def _implicit_json(imp: dict) -> dict:
    """The named intermediates as a self-contained contract: to evaluate an entry at a state,
    find each dependent coordinate from its closed form or as the root of the constraints on
    the branch through its initial value, then solve ``G_d lambda = -G_i`` and
    ``G_d gamma = quadratic``."""
    return {
        "independent": imp["independent_names"],
        "choice": imp["choice"],
        "constraints": {c["name"]: c["expression"] for c in imp["constraints"]},
        "dependent": {d["plain"]: ({"closed_form": d["closed_form"]} if d["closed_form"] else
                                   {"root_of": [c["name"] for c in imp["constraints"]]}) | {"branch": d["branch"]}
                      for d in imp["dependent"]},
        "jacobian_dependent": imp["jacobian_dependent"],
        "jacobian_independent": imp["jacobian_independent"],
        "sensitivities": {s["plain"]: {"derivative": [s["of"], s["by"]], "expression": s["definition"] or None}
                          for s in imp["sensitivities"]},
        "convective": {g["plain"]: {"of": g["of"], "quadratic": g["quadratic"], "expression": g["definition"] or None}
                       for g in imp["convective"]},
        "evaluation": "dependent from closed_form, else Newton on constraints from branch; "
                      "jacobian_dependent * [sensitivities] = -jacobian_independent; "
                      "jacobian_dependent * [convective] = [quadratic]",
    }


EMITTERS = {"markdown": emit_markdown, "latex": emit_latex, "json": emit_json}


__all__ = ["EMITTERS", "emit_json", "emit_latex", "emit_markdown", "template_environment"]
