"""What every text emitter shows, as plain data: the derivation step by step.

Like the paper: the primitive metric and forces (16), (17), the connection
(19) and ``C`` (21), the projected metric (22), forces (23), velocity terms
(E), the energies (24) and the equations of motion (10').
"""
from __future__ import annotations

import functools
from itertools import count
from typing import Callable, Iterable, Mapping

import sympy
from markupsafe import Markup
from sympy.printing.str import StrPrinter

from ..core.known_system import KnownSystem
from ..core.canonical import add, mul
from ..core.printed import RememberingStr
from ..core.rheonomic import depends_on_time, project_frozen
from ..core.operations import count_ops
from ..core.simplify import recompact, tidy
from .escape import latex_name
from .latex_layout import LatexPrinter, unbroken
from ..core.derivative import derivative
from ..core.symbols import TIME, acceleration_symbol, velocity_symbol

Printer = Callable[[sympy.Expr], str]


class ModelStrPrinter(RememberingStr, StrPrinter):
    """sympy's ``str`` form in the words of the model's expression parser
    (:mod:`kronsub.model.expressions`), so that every printed expression reads back to
    the same value: ``Abs`` is ``abs``, Euler's number ``exp(1)``; ``pi`` is ``acos(-1)``
    when the model has a name ``pi`` of its own; a symbol of ``renamed`` (a charge's velocity)
    is printed under its name there (the current, :mod:`kronsub.core.currents`). It remembers
    what it printed: one printer per report."""

    def __init__(self, reserved: Iterable[str] = (), renamed: Mapping[sympy.Symbol, str] | None = None):
        super().__init__({"order": "lex"})
        self.reserved = frozenset(reserved)
        self.renamed = dict(renamed or {})

    def _print_Symbol(self, expr):
        name = self.renamed.get(expr)
        return name if name is not None else StrPrinter._print_Symbol(self, expr)

    def _call(self, name: str, *args) -> str:
        return f"{name}({', '.join(self._print(a) for a in args)})"

    def _print_Abs(self, expr):
        return self._call("abs", expr.args[0])

    def _print_Exp1(self, expr):
        return "exp(1)"

    def _print_Pi(self, expr):
        return "acos(-1)" if "pi" in self.reserved else "pi"

    def _print_Heaviside(self, expr):  # sympy's Heaviside(0) is 1/2, as (sign(0) + 1)/2
        return f"((sign({self._print(expr.args[0])}) + 1)/2)"

    def _print_cot(self, expr):
        return f"(1/tan({self._print(expr.args[0])}))"

    def _print_sec(self, expr):
        return f"(1/cos({self._print(expr.args[0])}))"

    def _print_csc(self, expr):
        return f"(1/sin({self._print(expr.args[0])}))"


def plain_printer(reserved: Iterable[str] = (), renamed: Mapping[sympy.Symbol, str] | None = None) -> Printer:
    """The ``str`` form for a model whose own names are ``reserved``, the symbols of ``renamed``
    under their names there."""
    printer = ModelStrPrinter(reserved, renamed)
    return printer.doprint


def plain(expr) -> str:
    """sympy's ``str`` form, readable by the model's parser: the JSON contract and the Markdown tables."""
    return ModelStrPrinter().doprint(expr)


def model_names(system: KnownSystem) -> frozenset[str]:
    """Every name the system's expressions may use: parameters, coordinates, velocities..."""
    names = {p.name for p in system.parameters} | {q.name for q in (*system.coordinates, *system.velocities)}
    names.update(system.currents.values())
    exprs = (*system.mass_matrix, *system.velocity_terms, *system.forces, system.potential_energy)  # T: M's, qdot's
    names.update(s.name for s in _free_symbols(exprs))
    return frozenset(names)


def _distinct_nodes(exprs, descend=lambda node: True):
    """The subexpressions of ``exprs``, each object once, told apart by identity (the entries of a
    large system share their sums; an equal copy is walked again, in less time than ``==``
    compares the two); the arguments of a node are walked where ``descend(node)``."""
    seen: set = set()  # ids of nodes of exprs, alive while they are
    stack = [e for e in exprs if isinstance(e, sympy.Basic)]
    while stack:
        node = stack.pop()
        if id(node) in seen:
            continue
        seen.add(id(node))
        yield node
        if descend(node):
            stack.extend(node.args)


def _leaf(node) -> bool:
    """An atom, a node without arguments, or one that binds its variables (an integral)."""
    return node.is_Atom or not node.args or _binds(type(node))


def _free_symbols(exprs) -> set:
    """The free symbols of ``exprs``, each subexpression object walked once (:func:`_distinct_nodes`:
    ``free_symbols`` would walk the shared sums in every entry)."""
    found: set = set()
    for node in _distinct_nodes(exprs, lambda node: not _leaf(node)):
        if _leaf(node):
            found |= node.free_symbols
    return found


@functools.lru_cache(maxsize=None)
def _binds(cls: type) -> bool:
    """Whether ``cls`` has free symbols of its own rule (an integral binds its variable): the
    first ``free_symbols`` along its MRO is not ``Basic``'s (a function class's own attribute
    of that name, its metaclass's, is not the values')."""
    return next(k for k in cls.__mro__ if "free_symbols" in vars(k)) is not sympy.Basic


NAME_PREFIX = "w"
"""Named subexpressions are ``w1``, ``w2``... skipping any name the model uses."""
MIN_NAMED_OPS = 4
"""Operations a repeated subexpression of the coordinates needs to be named (``sqrt(1 - u**2)``)."""


def _uses(exprs, names: set) -> dict:
    """How many of ``exprs`` contain each symbol of ``names`` (``sum(e.has(s) for e in exprs)``,
    in one walk of each expression instead of one walk a name)."""
    uses = dict.fromkeys(names, 0)
    for e in exprs:
        for s in e.atoms(sympy.Symbol) & names:
            uses[s] += 1
    return uses


def _repeats(exprs, coordinates) -> bool:
    """Whether a root, a non-integer power or a function other than sine and cosine of
    the coordinates occurs twice: the subexpressions worth a name (a chain has none)."""
    if not _any_of_a_named_kind(exprs):
        return False
    # one that occurs twice is met again inside some subexpression met twice: each distinct
    # subexpression is walked once, and one met again asked whether it holds one
    holds: dict = {}

    def held(node) -> bool:
        hit = holds.get(node)
        if hit is None:
            hit = holds[node] = _worth_a_name(node, coordinates) or any(held(a) for a in node.args)
        return hit

    seen: set = set()
    stack = [e for e in exprs if isinstance(e, sympy.Basic)]
    while stack:
        node = stack.pop()
        if node in seen:
            if held(node):
                return True
            continue
        seen.add(node)
        stack.extend(node.args)
    return False


def _any_of_a_named_kind(exprs) -> bool:
    """Whether some subexpression of ``exprs`` is a non-integer power or a function other than
    sine and cosine (of anything), each object walked once (:func:`_distinct_nodes`)."""
    return any((node.is_Pow and not node.exp.is_Integer)
               or (isinstance(node, sympy.Function) and not isinstance(node, (sympy.sin, sympy.cos)))
               for node in _distinct_nodes(exprs))


def _worth_a_name(sub, coordinates) -> bool:
    """A root, a non-integer power or a function other than sine and cosine of the coordinates,
    of at least `MIN_NAMED_OPS` operations."""
    return ((sub.is_Pow and not sub.exp.is_Integer)
            or (isinstance(sub, sympy.Function) and not isinstance(sub, (sympy.sin, sympy.cos)))) \
        and bool(sub.free_symbols & coordinates) and count_ops(sub) >= MIN_NAMED_OPS


def named_subexpressions(exprs: list, taken: Iterable[str], coordinates) -> tuple[list, list]:
    """Repeated subexpressions named once (a "where" block): ``([(name, expr)...], reduced)``.

    ``sympy.cse`` finds every repeated subexpression; the small ones are put back, so a
    name stands for something worth reading once (``sqrt(1 - (c - a1*sin(theta))**2/a2**2)``
    in System II); only what varies with the coordinates is named, so ``m1 + 2*m2`` stays
    inline. Names are ``w1, w2...`` in order of definition, skipping ``taken``.
    """
    taken = frozenset(taken)
    coordinates = frozenset(coordinates)
    if not _repeats(exprs, coordinates):
        return [], list(exprs)
    names = (sympy.Symbol(f"{NAME_PREFIX}{i}") for i in count(1) if f"{NAME_PREFIX}{i}" not in taken)
    replacements, reduced = sympy.cse(exprs, symbols=names, order="canonical")
    entries = set(reduced)
    pending = list(replacements)
    while True:  # put back the small ones, whole entries and those used once
        dropped: dict = {}
        kept = []
        uses = _uses(reduced + [e for _, e in pending], {sym for sym, _ in pending})
        for sym, expr in pending:
            expr = expr.xreplace(dropped)
            ops = count_ops(expr)
            varying = bool(expr.free_symbols & coordinates)
            if ops < MIN_NAMED_OPS or not varying or sym in entries or uses[sym] < 2:
                dropped[sym] = expr
            else:
                kept.append((sym, expr))
        reduced = [e.xreplace(dropped) for e in reduced]
        entries = set(reduced)
        if not dropped:
            break
        pending = kept
    # renumber what is kept: w1, w2... without gaps
    fresh = (sympy.Symbol(f"{NAME_PREFIX}{i}") for i in count(1) if f"{NAME_PREFIX}{i}" not in taken)
    rename = {sym: next(fresh) for sym, _ in kept}
    kept = [(rename[s], e.xreplace(rename)) for s, e in kept]
    reduced = [e.xreplace(rename) for e in reduced]
    return kept, reduced


def latex_printer(coordinates, implicit=None, breaks: bool = False, currents: Mapping[str, str] | None = None) -> Printer:
    """LaTeX with velocities as dots: ``theta_dot`` -> ``\\dot{\\theta}``, a charge's as its current
    (``currents``: ``qa_dot`` -> ``i_{a}``); with implicit constraints
    ``lambda_phi_theta`` -> ``\\lambda_{\\phi\\theta}`` and ``gamma_phi`` -> ``\\gamma_{\\phi}``.
    With ``breaks``, the terms of a top-level sum are separated by `BREAK` (for `lines`)."""
    names = {}
    if implicit is not None:
        for a, d in enumerate(implicit.dependent):
            for j, q in enumerate(implicit.independent):
                s = implicit.sensitivities[a, j]
                names[s] = (r"\lambda" if s.name == "lambda" else
                            rf"\lambda_{{{latex_name(d.name)}{latex_name(q.name)}}}")
            g = implicit.convective[a]
            names[g] = r"\gamma" if g.name == "gamma" else rf"\gamma_{{{latex_name(d.name)}}}"
    for q in coordinates:
        base = latex_name(q.name)
        current = (currents or {}).get(q.name)
        names[velocity_symbol(q)] = rf"\dot{{{base}}}" if current is None else current_latex(current)
        names[acceleration_symbol(q)] = (rf"\ddot{{{base}}}" if current is None or current.endswith("_dot")
                                         else rf"\dot{{{current_latex(current)}}}")

    printer = LatexPrinter({"symbol_names": names, "order": "lex", "escaped_names": True})

    def show(expr) -> str:
        text = printer.doprint(expr)
        return text if breaks else unbroken(text)

    return show


def current_latex(name: str) -> str:
    """A current's name in LaTeX (``i_a`` -> ``i_{a}``); one kept as a velocity (``q_dot``) as a dot."""
    return rf"\dot{{{latex_name(name[:-4])}}}" if name.endswith("_dot") else latex_name(name)


def matrix_rows(matrix: sympy.Matrix, show: Printer) -> list[list[str]]:
    return [[show(e) for e in row] for row in matrix.tolist()]


def _once(show: Printer) -> Printer:
    """``show`` printing each distinct expression once (``Mbar``'s entries appear in both of its
    triangles and again in the equations' parts)."""
    printed: dict = {}

    def once(expr):
        key = (type(expr), expr)
        text = printed.get(key)
        if text is None:
            text = printed[key] = show(expr)
        return text

    return once


Products = list
"""Terms ``(entry, coefficient, factors)``: the product ``coefficient * entry * prod(factors)``."""
SumPrinter = Callable[[Products, Iterable[sympy.Expr]], str]
"""The printed sum of the products and other terms (`sum_printer`)."""


def kinetic_energy(mass: sympy.Matrix, velocities) -> sympy.Expr:
    """``T = 1/2 Mbar_ab qdot^a qdot^b`` as the paper prints (24), `kinetic_terms` added."""
    return add([_product(entry, *factors, coefficient=c) for entry, c, factors in kinetic_terms(mass, velocities)])


def kinetic_terms(mass, velocities) -> Products:
    """The terms of ``T = 1/2 Mbar_ab qdot^a qdot^b`` (24): one for each entry of the upper
    triangle, ``Mbar_aa qdot_a^2 / 2`` and ``Mbar_ab qdot_a qdot_b``, the entries as printed
    (not multiplied out: a chain's entries hold sums of masses, whose products with the
    velocities would be far longer to print, and to make); ``mass`` a list of rows."""
    half = sympy.Rational(1, 2)
    n = len(velocities)
    return [(mass[a][a], half, (velocities[a] ** 2,)) if a == b  # 1/2 not distributed
            else (mass[a][b], sympy.S.One, (velocities[a], velocities[b]))
            for a in range(n) for b in range(a, n) if mass[a][b] != 0]


def sum_printer(show: Printer) -> SumPrinter:
    """The printed sum of products and other terms: ``show`` of the sum formed."""
    return lambda products, others: show(add([*[_product(entry, *factors, coefficient=c)
                                                 for entry, c, factors in products], *others]))


def _product(entry: sympy.Expr, *factors: sympy.Expr, coefficient: sympy.Rational = sympy.S.One) -> sympy.Expr:
    """``sympy.Mul(coefficient, entry, *factors)``, the very expression, built from an entry's
    factors in canonical order (:func:`..core.canonical.mul`) without sympy's flattening of
    each product anew."""
    if entry.is_Mul and entry.is_commutative:
        c, rest = entry.as_coeff_Mul()
        if c.is_Rational:
            return mul(coefficient * c, [*sympy.Mul.make_args(rest), *factors])
    return sympy.Mul(coefficient, entry, *factors)


def with_names(expr: sympy.Expr, where: list) -> sympy.Expr:
    """``expr`` written with the names of the "where" block, as the entries of ``fbar`` are: each
    name's whole expression (earlier names put back) replaced by the name, the largest first;
    SymPy's ``subs`` also finds one inside a longer product or sum (``2*h*a*b`` is ``a*w3``
    where ``w3 = 2*h*b``). An exact rewriting: putting the expressions back gives ``expr``."""
    if not where or expr == 0:
        return expr
    full: dict = {}
    for name, named in where:
        full[name] = named.xreplace(full)
    symbols = expr.free_symbols
    pairs = [(e, name) for name, e in full.items() if e.free_symbols <= symbols]
    return expr.subs(sorted(pairs, key=lambda pair: -count_ops(pair[0]))) if pairs else expr


def build_report(system: KnownSystem, show: Printer, named: bool = True, names: frozenset[str] | None = None,
                 sums: SumPrinter | None = None) -> dict:
    """The derivation as nested lists of printed strings, in a fixed order.

    With ``named``, subexpressions repeated across the projected system and the equations
    are printed once, in ``where`` (:func:`named_subexpressions`), under names other than
    the model's (``names``: :func:`model_names`, when the caller has them already). ``sums``
    prints the equations' left-hand sides and the kinetic energy from the entries' terms
    (the printer's own, such as `ModelStrPrinter.sum_of_products`, that need not form them;
    :func:`sum_printer` of ``show`` when not given).
    """
    show = _once(show)
    sums = sums or sum_printer(show)
    tr = system.transition
    n = len(system.coordinates)
    effects = list(system.effect_forces.items())
    forces = [recompact(f, system.coordinates) if sum(e[i] != 0 for _, e in effects) > 1 else tidy(f)
              for i, f in enumerate(system.forces)]
    upper = [(i, j) for i in range(n) for j in range(i, n)]
    exprs = [*[tidy(system.mass_matrix[i, j]) for i, j in upper], *[tidy(h) for h in system.velocity_terms], *forces]
    where: list = []
    if named:
        where, exprs = named_subexpressions(exprs, model_names(system) if names is None else names,
                                            system.coordinates)
    mass = sympy.zeros(n, n)
    for (i, j), e in zip(upper, exprs):
        mass[i, j] = mass[j, i] = e
    hbar, fbar = exprs[len(upper):len(upper) + n], exprs[len(upper) + n:]
    named_as = {e: s for s, e in where}
    others = [system.potential_energy.xreplace(named_as), *[with_names(e, where) for _, f in effects for e in f]]
    it = iter(others[1:])
    take = lambda k: [next(it) for _ in range(k)]  # noqa: E731
    rows = mass.tolist()
    accelerations = system.accelerations
    one = sympy.S.One
    report = {
        **report_head(system, show),
        "mass_matrix": matrix_rows(mass, show),
        "velocity_terms": [show(e) for e in hbar],
        "forces": [show(e) for e in fbar],
        "effects": [{"name": k, "forces": [show(e) for e in take(len(f))]} for k, f in effects],
        "kinetic_energy": sums(kinetic_terms(rows, system.velocities), ()),
        "potential_energy": show(others[0]),
        "accelerations": [show(a) for a in accelerations],
        # Mbar qddot + hbar, each row one sum (the matrix product adds its terms one at a time)
        "equations": [{"lhs": sums([(e, one, (a,)) for e, a in zip(rows[i], accelerations)],
                                   () if hbar[i] == 0 else sympy.Add.make_args(hbar[i])),
                       "rhs": show(fbar[i])} for i in range(n)],
        "where": [{"name": show(s), "plain": s.name, "expression": show(e)} for s, e in where],
    }
    if tr is not None:
        report["primitive"] = primitive_report(system, show)
    if system.implicit is not None:
        report["implicit"] = implicit_report(system.implicit, show)
    return report


def report_head(system: KnownSystem, show: Printer) -> dict:
    """The name, description, coordinates and parameters of ``system``, as printed."""
    return {
        "name": system.name,
        "description": system.description.strip(),
        "coordinates": [show(q) for q in system.coordinates],
        "coordinate_names": [q.name for q in system.coordinates],
        "parameters": [
            {"name": p.name, "symbol": show(p.symbol), "value": "" if p.value is None else show(p.value),
             "unit": p.unit, "description": p.description}
            for p in system.parameters
        ],
    }


def primitive_report(system: KnownSystem, show: Printer) -> dict:
    """The primitive system of ``system``'s transition: its metric (16), velocity terms and forces
    (17), the connection (19) and ``C`` (21), and a drive's terms."""
    tr = system.transition
    report = {
        "parts": [{"name": n, "type": t or "known system"} for n, t in tr.parts],
        "coordinates": [show(x) for x in tr.primitive_coordinates],
        "metric": matrix_rows(tr.primitive_metric, show),
        "velocity_terms": [show(e) for e in tr.primitive_velocity_terms],
        "forces": [{"name": k, "forces": [show(e) for e in f]} for k, f in tr.primitive_forces.items()
                   if k not in tr.direct_effects],
        "applied_in_subspace": list(tr.direct_effects),
        "connection": [{"coordinate": show(x), "expression": show(e)} for x, e in tr.connection],
        "transformation": matrix_rows(tr.transformation, show),
        "columns": [show(q) for q in _columns(system)],
    }
    drive = drive_report(system, show)
    if drive is not None:
        report["drive"] = drive
    return report


def drive_report(system: KnownSystem, show: Printer) -> dict | None:
    """A connection that names time (a prescribed motion, :mod:`..core.rheonomic`): the drive's
    velocity ``s = dx/dt`` and the terms it adds to ``hbar``; ``None`` for ``x = x(xbar)``."""
    tr = system.transition
    connection = dict(tr.connection)
    if system.implicit is not None or not depends_on_time(connection):
        return None
    frozen = project_frozen(tr.primitive_coordinates, tr.primitive_metric, tr.primitive_velocity_terms,
                            connection, system.coordinates)
    extra = [tidy(sympy.trigsimp(sympy.expand(h - f))) for h, f in zip(system.velocity_terms, frozen)]
    return {
        "velocity": [show(derivative(e, TIME)) for _, e in tr.connection],
        "velocity_terms": [show(e) for e in extra],
    }


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


__all__ = ["MIN_NAMED_OPS", "ModelStrPrinter", "NAME_PREFIX", "Printer", "Products", "SumPrinter", "build_report",
           "implicit_report", "kinetic_energy", "kinetic_terms", "latex_printer", "matrix_rows", "model_names",
           "named_subexpressions", "plain", "plain_printer", "primitive_report", "report_head", "sum_printer"]
