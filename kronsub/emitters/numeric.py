"""What generated code computes, prepared once for every language.

``Mbar qddot + hbar = fbar`` (10') becomes the first-order system
``ydot = [qdot; Mbar^-1 (fbar - hbar)]`` with state ``y = [q; qdot]``, and the
canonical form ``z = [q; p]``, ``p = Mbar qdot``,
``zdot = [Mbar^-1 p; dT/dq + fbar]`` (Lagrange's equations (A) with
``dT/dq = 1/2 qdot^T (dMbar/dq) qdot``), used by the symplectic integrator. With first-order coordinates ``J``
(:mod:`kronsub.core.first_order`, a zero row of ``Mbar``) the rates of ``q_J`` are their solved
velocities, written after ``r`` (``r[n:]``), and their rows of ``Mbar`` the identity with
``r_J = 0``: the ``qdot_J`` slots of the state are not integrated.
Common subexpressions are eliminated per function, deterministically.
"""
from __future__ import annotations

import functools
import math
import re
from dataclasses import dataclass

import sympy
from sympy.simplify.cse_main import basic_optimizations as _BASIC

from ..core.derivative import derivative
from ..core.first_order import first_order
from ..core.known_system import KnownSystem
from ..core.projection_work import projected_in_numbers
from ..core.rheonomic import depends_on_time
from ..core.sympy_internals import eval_evalf
from ..core.symbols import TIME, free_symbols_of
from ..errors import KronsubError
from .block import Block
from .numeric_held import HeldCode, held_code
from .numeric_implicit import ImplicitCode, implicit_code, intermediate_slots
from .projected import ProjectedCode, projected_by_size, projected_code
from .projected_speeds import FrameCode, frame_code
from .projected_speeds import applies as frame_applies


@dataclass(frozen=True)
class NumericModel:
    """A derived system in the shape generated code needs it."""

    name: str
    source: str
    coordinates: tuple[str, ...]
    parameters: tuple[tuple[str, str, str], ...]  # (name, default value or "", unit)
    points: tuple[tuple[str, int], ...]  # (label, dimension), in output order
    mass: Block  # Mbar (row-major, full) into M[]
    velocity_terms: Block  # hbar into h[]
    forces: Block  # fbar into f[]
    equations: Block  # Mbar into M[] and fbar - hbar into r[], sharing subexpressions (in pre[])
    canonical: Block  # dT/dq + fbar into r[] (in pre[])
    prepare: Block  # the derived constants pre[n_param:] from param[]
    n_pre: int  # length of pre = [param; derived constants; the Newton state of implicit constraints]
    potential: Block  # V
    positions: Block  # named points into out[]
    energies: bool = True  # emit T and V (a scene may not ask for them)
    with_points: bool = True  # emit the named points' positions

    implicit: ImplicitCode | None = None  # the dependent-coordinate solve
    timed: bool = False  # the connection names t (x = x(xbar, t)): velocity_terms and points take t first
    first_order: tuple[int, ...] = ()  # first-order coordinates J: qdot_J into r[n:], rows J of M identity, r_J = 0
    jacobian: Block | None = None  # d ydot/dy: V (rates of q, n x 2n), K = dr/dy (n x 2n), G = dMbar/dq_k (n x n x n)
    speeds: tuple[str, ...] = ()  # under velocity constraints: the speeds u, the state [q; u]
    kinematics: Block | None = None  # qdot = C(q) u into xd[] (in pre[])
    held: HeldCode | None = None  # configuration constraints beside velocity constraints: q_D by Newton's method
    projected: ProjectedCode | None = None  # Mbar, hbar, fbar formed at run time (the blocks above empty)
    frame: FrameCode | None = None  # under velocity constraints: the projection onto the speeds at run time
    velocities: tuple[str, ...] = ()  # the velocities' printed names (a charge's: its current); default q_dot
    terms_apart: bool = True  # emit hbar and fbar each on its own (a run's library needs neither)
    with_canonical: bool = True  # emit the canonical right-hand side (only gauss4 integrates it)
    mass_apart: bool = True  # Mbar from a block of its own (else mass is the equations' block's part for Mbar)

    @property
    def n(self) -> int:
        return len(self.coordinates)

    @property
    def nv(self) -> int:
        """The velocity part of the state: the speeds under velocity constraints, else ``qdot``."""
        return len(self.speeds) if self.speeds else self.n

    @property
    def state(self) -> tuple[str, ...]:
        if self.speeds:
            return self.coordinates + self.speeds
        return self.coordinates + (self.velocities or tuple(f"{q}_dot" for q in self.coordinates))


def identifier(text: str) -> str:
    """A C/Python identifier made from a model name."""
    out = re.sub(r"[^0-9A-Za-z_]+", "_", text).strip("_").lower() or "model"
    return out if not out[0].isdigit() else f"m_{out}"


def _default(value) -> str:
    """A parameter's default as a decimal literal ("" when it has none or it is not finite)."""
    if value is None or not sympy.sympify(value).is_number:
        return ""
    number = float(value)
    return repr(number) if math.isfinite(number) else ""


GUARD = sympy.Rational(1, 8)
"""Below this magnitude a sine or cosine of several coordinates is not taken from products."""


class NearAxis(sympy.Function):
    """``NearAxis(L, 0, P)`` is ``sin(L)``, ``NearAxis(L, 1, P)`` is ``cos(L)``, ``P`` their
    single-angle products: the generated C takes ``P`` unless ``|P| < 1/8``, where ``P`` lost
    digits, and then evaluates ``<p>_near_axis(L, kind, P)`` (``model.c.j2``: ``L`` less the
    nearest multiple of pi/2, taken in three parts, then a Taylor polynomial; ``P`` where ``|L|``
    is beyond 2^20). One node, not a ``Piecewise``: ``cse`` rebuilding a condition
    ``|P| < 1/8`` asks the assumptions system about the sign of ``P`` every time. ``P`` is
    given twice (``NearAxis(L, kind, P, P)``) because the C uses it three times: so ``cse``
    names it."""

    nargs = 4

    def _eval_evalf(self, prec):
        angle, kind = self.args[:2]
        return eval_evalf((sympy.cos if kind else sympy.sin)(angle), prec)


EXPANDED_MULTIPLE = 4
"""Highest multiple ``k`` whose ``cos(k a)``, ``sin(k a)`` are written as polynomials in ``cos a``
and ``sin a`` (``expand_trig``): their coefficients grow as ``(1 + sqrt 2)^k``, and so does the
rounding error of the power form (at ``k = 12`` it lost half the digits; at ``k = 80`` every
one). A higher multiple is formed by :func:`multiple_angle`, whose error grows as ``k``."""


def multiple_angle(q: sympy.Symbol, k: int) -> tuple[sympy.Expr, sympy.Expr]:
    """``(cos(k q), sin(k q))`` from ``cos q`` and ``sin q`` by doubling and adding angles
    (``cos 2a = cos^2 a - sin^2 a``, ``sin 2a = 2 sin a cos a``, then one addition per binary
    digit of ``k``), each step a rotation whose rounding adds to the error, never multiplies
    it: ``log2 k`` named pairs that ``cse`` shares between entries."""
    if k < 0:
        c, s = multiple_angle(q, -k)
        return c, -s
    if k == 0:
        return sympy.Integer(1), sympy.Integer(0)
    if k == 1:
        return sympy.cos(q), sympy.sin(q)
    if k % 2 == 0:
        c, s = multiple_angle(q, k // 2)
        return sympy.Add(c * c, -(s * s)), 2 * s * c
    c, s = multiple_angle(q, k - 1)
    c1, s1 = sympy.cos(q), sympy.sin(q)
    return sympy.Add(c * c1, -(s * s1)), sympy.Add(s * c1, c * s1)


def _angle_sum(atom: sympy.Expr) -> sympy.Expr:
    """``sin(L)`` or ``cos(L)`` expanded into single-angle sines and cosines (``expand_trig``,
    written out directly for the common ``L = +-a +- b``; by :func:`multiple_angle` and the
    addition theorem, unexpanded, where a multiple exceeds :data:`EXPANDED_MULTIPLE`)."""
    terms = sympy.Add.make_args(atom.args[0])
    parts = [t.as_coeff_Mul() for t in terms]
    if len(terms) == 2:
        (c1, a), (c2, b) = parts
        if abs(c1) == 1 and abs(c2) == 1 and a.is_Symbol and b.is_Symbol:
            sa, ca, sb, cb = sympy.sin(a), sympy.cos(a), sympy.sin(b), sympy.cos(b)
            if isinstance(atom, sympy.sin):
                return sympy.Add(c1 * sa * cb, c2 * ca * sb)
            return sympy.Add(ca * cb, -c1 * c2 * sa * sb)
    if any(c.is_Integer and abs(int(c)) > EXPANDED_MULTIPLE and q.is_Symbol for c, q in parts):
        c, s = sympy.Integer(1), sympy.Integer(0)
        for k, q in parts:  # cos(L + k q) and sin(L + k q) by the addition theorem
            ck, sk = multiple_angle(q, int(k)) if k.is_Integer and q.is_Symbol else (sympy.cos(k * q), sympy.sin(k * q))
            c, s = sympy.Add(c * ck, -(s * sk)), sympy.Add(s * ck, c * sk)
        return s if isinstance(atom, sympy.sin) else c
    return sympy.expand(sympy.expand_trig(atom))


@functools.lru_cache(maxsize=4096)
def _guarded(atom: sympy.Expr) -> sympy.Expr:
    """``sin(L)`` or ``cos(L)`` of several coordinates through single-angle sines and cosines
    (shared by every entry), except where those products lose relative accuracy: a value of
    magnitude below 1/8 (``L`` near a multiple of pi, or a cosine's near pi/2) is taken by
    :class:`NearAxis` from ``L`` (whose remainder near 0 is ``L`` itself, exact when the angles
    are close: Sterbenz). It calls no libm function: a call in the right-hand side would keep
    every double it holds on the stack (no vector register survives a call)."""
    products = _angle_sum(atom)
    kind = sympy.Integer(int(isinstance(atom, sympy.cos)))
    return NearAxis(atom.args[0], kind, products, products)


def _single_angles(exprs: list[sympy.Expr], coordinates, guarded: bool = False, plain: int = 0) -> list[sympy.Expr]:
    """Rewrite multiple angles of one coordinate (``sin(2 q1) = 2 sin(q1) cos(q1)``) through
    its sine and cosine, which then serve every entry (common subexpressions).

    An angle of several coordinates (``sin(q1 - q2)``) needs care: through single-angle sines
    and cosines, ``sin(q1) cos(q2) - cos(q1) sin(q2)`` loses the digits the two products share
    when ``q1`` is close to ``q2``, while ``q1 - q2`` is then exact (Sterbenz) and so is its
    sine, to one rounding (tests/hard/test_hard_cancellation.py). Unguarded it stays as it is,
    one libm call per angle; ``guarded`` (the C right-hand sides), :func:`_guarded`: a chain
    of n links then calls ``sincos`` n times, not n^2 / 2 times. The first ``plain`` expressions
    (guarded: the entries of ``Mbar``) take the products without a guard: ``Mbar`` enters only
    through the ``L D L^T`` solve, whose rounding is already of the order of eps times the
    largest entry, so an entry's relative accuracy below that is not used.
    """
    coords = set(coordinates)
    mappings: tuple[dict, dict] = ({}, {})  # (the first `plain` expressions', the others')
    for index, expr in enumerate(exprs):
        mapping = mappings[index >= plain]
        for atom in expr.atoms(sympy.sin, sympy.cos):
            terms = sympy.Add.make_args(atom.args[0])
            parts = [t.as_coeff_Mul() for t in terms]
            if not all(c.is_Integer and q in coords for c, q in parts):
                continue
            if len(parts) == 1 and abs(int(parts[0][0])) > EXPANDED_MULTIPLE:
                c, s = multiple_angle(parts[0][1], int(parts[0][0]))
                mapping[atom] = s if isinstance(atom, sympy.sin) else c
            elif len(parts) == 1 and abs(int(parts[0][0])) > 1:
                mapping[atom] = sympy.expand_trig(atom)
            elif len(parts) > 1 and guarded:
                mapping[atom] = _guarded(atom) if index >= plain else _angle_sum(atom)
    return [e.xreplace(mapping) if (mapping := mappings[index >= plain]) else e for index, e in enumerate(exprs)]


class _Constants:
    """Moves what depends on the parameters alone out of the right-hand side.

    ``pre = [param; derived]``: products and sums of parameters (``l1*l2*(m2 + 2*m3)/2``)
    are computed once per parameter set by ``prepare``, not at every evaluation.
    """

    def __init__(self, params: list[sympy.Symbol]):
        self.params = set(params)
        self.names = {p: sympy.Symbol(f"pre[{i}]") for i, p in enumerate(params)}
        self.derived: dict[sympy.Expr, sympy.Symbol] = {}
        self.count = len(params)
        self.constant: dict[sympy.Expr, bool] = {}  # e -> whether it names parameters alone
        self.done: dict[sympy.Expr, sympy.Expr] = {}  # e -> its image (a long entry's parts recur)

    def _constant(self, e: sympy.Expr) -> bool:
        """``e.free_symbols <= params``, from its arguments' (remembered) where they are its own."""
        hit = self.constant.get(e)
        if hit is None:
            if e.is_Atom or not (e.is_Add or e.is_Mul or e.is_Pow or isinstance(e, sympy.Function)):
                hit = e.free_symbols <= self.params
            else:
                hit = all(self._constant(a) for a in e.args)
            self.constant[e] = hit
        return hit

    def _name(self, e: sympy.Expr) -> sympy.Expr:
        if e in self.names:
            return self.names[e]
        if e not in self.derived:
            self.derived[e] = sympy.Symbol(f"pre[{self.count}]")
            self.count += 1
        return self.derived[e]

    def __call__(self, e: sympy.Expr) -> sympy.Expr:
        hit = self.done.get(e)
        if hit is None:
            hit = self.done[e] = self._image(e)
        return hit

    def _image(self, e: sympy.Expr) -> sympy.Expr:
        if e.is_Number:
            return e
        if e.is_Atom:
            return self.names.get(e, e)
        if self._constant(e):
            return self._name(e)
        if e.is_Mul or e.is_Add:
            const = [a for a in e.args if self._constant(a)]
            rest = [self(a) for a in e.args if not self._constant(a)]
            if any(not a.is_Number for a in const):
                group = e.func(*const)
                rest.insert(0, self._name(group) if not group.is_Number else group)
            else:
                rest = const + rest
            return e.func(*rest)
        return e.func(*[self(a) for a in e.args])

    def index(self, e: sympy.Expr) -> int:
        """The slot of ``pre`` that holds ``e`` (of the parameters alone; a number too)."""
        if not self._constant(e):
            raise ValueError(f"{e} is not a constant of the parameters")
        return int(self._name(e).name[len("pre["):-1])

    def reserve(self, count: int) -> int:
        """The first of ``count`` slots of ``pre`` that ``prepare`` fills after the definitions."""
        first = self.count
        self.count += count
        return first

    def definitions(self) -> tuple[list[str], list[sympy.Expr]]:
        return [s.name for s in self.derived.values()], list(self.derived)


BASIC_NODES = 20000
"""Expression nodes of a block up to which ``cse`` also tries its "basic" rewritings (pulling
out negated and common factors of sums). They save a tenth of the operations of a 3-D box on
springs' right-hand side (5,664 nodes) and none of a chain's, where they take several times as
long as the elimination itself; a block's size does not tell the two apart, so the bound only
keeps the rewritings of very large blocks from taking minutes (benchmarks/HISTORY.md)."""


def _more_nodes_than(exprs, limit: int) -> bool:
    count = 0
    for expr in exprs:
        for _ in sympy.preorder_traversal(expr):
            count += 1
            if count > limit:
                return True
    return False


def settled(expr: sympy.Expr) -> bool:
    """Whether ``cse``'s "basic" rewritings certainly leave ``expr`` as it is: no sum in it
    (inside functions and powers too) could give up a minus sign (what ``sub_pre`` pulls
    out), and none has a factor common to all its terms, a common sign or a common integer
    content (what ``factor_terms`` pulls out); its numbers integers or rationals, its powers
    positive integer ones of single bases. False is no verdict: the rewritings then run. One
    walk of the tree, where ``factor_terms`` builds the factors of every term of every sum."""
    seen = set()
    stack = [expr]
    while stack:
        e = stack.pop()
        if e in seen:
            continue
        seen.add(e)
        if e.is_Atom:
            if not (e.is_Symbol or e.is_Rational):
                return False
            continue
        if not all(isinstance(a, sympy.Expr) for a in e.args):
            return False
        if e.is_Add:
            if e.could_extract_minus_sign():
                return False
            common, coefficients = None, []
            for term in e.args:
                coefficient, rest = term.as_coeff_Mul()
                if not coefficient.is_Integer:
                    return False
                coefficients.append(int(coefficient))
                bases = set()
                for factor in sympy.Mul.make_args(rest) if rest is not sympy.S.One else ():
                    if factor.is_Number:
                        return False
                    if factor.is_Pow:
                        base, exponent = factor.args
                        if not (exponent.is_Integer and exponent > 0) or base.is_Mul:
                            return False
                        factor = base
                    bases.add(factor)
                common = bases if common is None else common & bases
            if common or all(c < 0 for c in coefficients) or math.gcd(*coefficients) != 1:
                return False
        elif e.is_Pow:
            if e.args[0].is_Mul:
                return False
        elif not (e.is_Mul or e.is_Function):
            return False
        stack.extend(e.args)
    return True


class _Rewritings:
    """``cse``'s "basic" rewritings (negations pulled out of sums, then ``factor_terms``), each
    expression rewritten once per model (the blocks share most of their entries), and not at
    all where they would change nothing (:func:`settled`)."""

    def __init__(self):
        self.done: dict = {}

    def __call__(self, expr: sympy.Expr) -> sympy.Expr:
        hit = self.done.get(expr)
        if hit is None:
            hit = expr
            if not settled(expr):
                for rewrite, _ in _BASIC:
                    hit = rewrite(hit)
            self.done[expr] = hit
        return hit

    def optimizations(self) -> list:
        """The same steps as ``optimizations="basic"``, the rewritings remembered: every
        rewriting at once, then each undoing step as ``cse`` runs them (last first)."""
        return [(self, None)] + [(None, undo) for _, undo in _BASIC]


def _block(targets: list[str], exprs: list[sympy.Expr], prefix: str, coordinates=(), guarded: bool = False,
           rewritings: _Rewritings | None = None, plain: int = 0, rewrite: bool = True) -> Block:
    exprs = _single_angles(exprs, coordinates, guarded, plain)
    symbols = sympy.numbered_symbols(prefix)
    basic = None
    if rewrite and not _more_nodes_than(exprs, BASIC_NODES):
        basic = (rewritings or _Rewritings()).optimizations()
    replacements, reduced = sympy.cse(exprs, symbols=symbols, optimizations=basic, order="canonical")
    return Block(tuple(replacements), tuple(zip(targets, reduced)))


def jacobian_block(system: KnownSystem, first, slot) -> tuple[list[str], list[sympy.Expr]]:
    """Targets and expressions of the parts of ``d ydot/dy``, ``y = [q; qdot]``, ``ydot = [v; a]``,
    ``Mbar a = r``: ``V = dv/dy`` (``v = qdot``, or with first-order coordinates their solved
    velocities), ``K = dr/dy`` and ``G_k = dMbar/dq_k``, so that

        d a/dq_k = Mbar^-1 (K[:, k] - G_k a),    d a/dqdot = Mbar^-1 K[:, n:]

    (first-order coordinates: ``r`` with their velocities put in, their rows of ``Mbar`` the
    identity and of ``r`` zero, as in the right-hand side)."""
    n = len(system.coordinates)
    y = list(system.coordinates) + list(system.velocities)
    M, r = system.mass_matrix, system.forces - system.velocity_terms
    v = sympy.Matrix(system.velocities)
    if first is not None:
        r = r.xreplace(first.substitution(system))
        r = sympy.Matrix([0 if i in first.indices else r[i] for i in range(n)])
        M = sympy.Matrix(n, n, lambda i, j: int(i == j) if i in first.indices else M[i, j])
        for j, velocity in zip(first.indices, first.velocities):
            v[j] = velocity
    targets, exprs = [], []
    for i in range(n):
        for c in range(2 * n):
            targets += [f"V[{i * 2 * n + c}]", f"K[{i * 2 * n + c}]"]
            exprs += [slot(derivative(v[i], y[c])), slot(derivative(r[i], y[c]))]
    for k in range(n):
        for i in range(n):
            for j in range(n):
                targets.append(f"G[{k * n * n + i * n + j}]")
                exprs.append(slot(derivative(M[i, j], y[k])) if y[k] in M[i, j].free_symbols else sympy.Integer(0))
    return targets, exprs


def prepare(system: KnownSystem, source: str = "", outputs=None, guarded_angles: bool = False,
            jacobian: bool = False, route: str = "expanded", terms_apart: bool = True,
            canonical: bool = True, mass_apart: bool = True) -> NumericModel:
    """Map the system's symbols to array slots and eliminate common subexpressions.

    ``outputs`` (a scene's :class:`~kronsub.model.scenes.Outputs`; None: everything) leaves
    out the energies and the named points when they are not asked for. ``guarded_angles``
    (the C): the right-hand sides take sines and cosines of several coordinates from
    single-angle ones where that keeps their accuracy (:func:`_guarded`), and always in
    ``Mbar`` (:func:`_single_angles`). ``jacobian``: also the blocks of ``d ydot/dy``
    (:func:`jacobian_block`; not with implicit constraints). ``route`` (:data:`.projected.ROUTES`):
    ``projected`` keeps the projection for run time (:mod:`.projected`; the caller checks that it
    applies), ``auto`` does so for a large system (never with first-order coordinates or the exact
    Jacobian); under velocity constraints ``projected`` keeps the projection onto the speeds for run
    time (:mod:`.projected_speeds`), and ``auto`` does so when its symbolic projection is too large.
    ``terms_apart``: also ``hbar`` and ``fbar`` each on its own; ``canonical``: also the canonical
    form's ``dT/dq + fbar`` (a library that runs a method on ``y = [q; qdot]`` needs neither).
    ``mass_apart`` False: ``Mbar`` alone (the energies', the momentum's) is the equations' block's
    part for it (:meth:`.Block.part`, its constants in ``pre``) rather than eliminated again, where
    that block holds ``Mbar`` as it is (no first-order coordinate, no constraint): a run's library."""
    energies = outputs is None or outputs.energies
    with_points = outputs is None or bool(outputs.points)
    speeds = system.speeds  # under velocity constraints: the equations in the speeds, the state [q; u]
    velocities = speeds.speeds if speeds is not None else system.velocities
    n = len(velocities)  # Mbar is n x n
    # the projection onto the speeds at run time: the expressions in q, qdot (in qd[]) and t
    in_frame = speeds is not None and (route == "projected" or (
        route == "auto" and frame_applies(system) and projected_in_numbers(system)))  # (no exact Jacobian in speeds)
    params = [p for p in system.parameters]
    q_slots = {q: sympy.Symbol(f"q[{i}]") for i, q in enumerate(system.coordinates)}
    qd_slots = {v: sympy.Symbol(f"qd[{i}]") for i, v in enumerate(system.velocities if in_frame else velocities)}
    p_slots = {p.symbol: sympy.Symbol(f"param[{i}]") for i, p in enumerate(params)}
    slots = {**q_slots, **qd_slots, **p_slots, TIME: sympy.Symbol("t")}
    if len(slots) != len(q_slots) + len(qd_slots) + len(p_slots) + 1:
        shared = sorted(s.name for s in set(q_slots) & set(qd_slots) | set(p_slots) & (set(q_slots) | set(qd_slots))
                        | {TIME} & (set(q_slots) | set(qd_slots) | set(p_slots)))
        raise KronsubError(f"cannot generate code: {', '.join(shared)} would be two things at once (a parameter, "
                           "a coordinate, a velocity or t); rename the model's name")
    if system.implicit is not None:  # y_d, lambda, gamma: the named intermediates in w[]
        slots.update(intermediate_slots(system))

    slotted: dict = {}  # Mbar's entries come in equal pairs

    def slot(expr) -> sympy.Expr:
        expr = sympy.sympify(expr)
        if expr not in slotted:
            slotted[expr] = slot_once(expr)
        return slotted[expr]

    def slot_once(expr: sympy.Expr) -> sympy.Expr:
        unknown = expr.free_symbols - set(slots)
        if unknown:
            names = ", ".join(sorted(s.name for s in unknown))
            raise KronsubError(f"cannot generate code: {names} is neither a parameter, a coordinate, "
                               "a velocity nor t")
        if expr.has(sympy.DiracDelta):  # d sign(x)/dx: zero wherever the derivative exists
            expr = expr.replace(sympy.DiracDelta, lambda *args: sympy.Integer(0))
        return expr.xreplace(slots)

    block = functools.partial(_block, rewritings=_Rewritings())  # the blocks share their entries' rewritings
    if not in_frame:
        M = speeds.mass_matrix if speeds is not None else system.mass_matrix
        velocity_terms_of = speeds.velocity_terms if speeds is not None else system.velocity_terms
        forces_of = speeds.forces if speeds is not None else system.forces
        if TIME in free_symbols_of([M]):
            raise KronsubError("cannot generate code: Mbar depends on t (a prescribed motion that changes the "
                               "inertia); only hbar and fbar may name t in the generated code")
    # x = x(xbar, t): hbar has the drive's terms and the points move with t (velocity_terms and points take t)
    timed = system.transition is not None and depends_on_time(dict(system.transition.connection))
    if speeds is not None and not in_frame:  # A xdot + b(x, t) = 0: hbar holds d(t)'s terms
        timed = timed or TIME in free_symbols_of([speeds.velocity_terms])
    qs = tuple(q_slots.values())
    constants = _Constants(list(p_slots.values()))
    first = first_order(system) if speeds is None else None
    kinematics = exact = projected = frame = None
    r_targets = [f"r[{i}]" for i in range(n)]
    if in_frame:
        if not frame_applies(system):
            raise KronsubError("cannot keep the projection onto the speeds for run time: the system has no "
                               "primitive, an implicit subspace, a connection in time or an effect applied in the "
                               "subspace")
        block = functools.partial(_block, rewrite=False)
        frame = frame_code(system, slot, constants, lambda t, e: block(t, e, "x", qs, guarded_angles))
        timed = frame.timed
        mass = velocity_terms = forces = equations = Block((), ())
        canonical_block = block(r_targets, [sympy.Integer(0)] * n, "x", qs) if canonical else Block((), ())
    elif speeds is None and first is None and not jacobian and (
            route == "projected" or (route == "auto" and system.implicit is None and projected_by_size(system))):
        # no rewritings: in a large system's potential and points they cost more than the
        # elimination itself, and the projection's entries are short already
        block = functools.partial(_block, rewrite=False)
        projected = projected_code(system, slot, constants, lambda t, e: block(t, e, "x", qs, guarded_angles))
        mass = velocity_terms = forces = equations = canonical_block = Block((), ())
    else:
        r = forces_of - velocity_terms_of
        targets = [f"M[{i * n + j}]" for i in range(n) for j in range(n)]
        exprs = [slot(M[i, j]) for i in range(n) for j in range(n)]
        if first is None:
            equations = block(targets + r_targets, [constants(e) for e in exprs + [slot(e) for e in r]], "x", qs,
                              guarded_angles, plain=len(targets))
        else:  # the mixed system (core/first_order.py): M_JJ = 1, r_J = 0, qdot_J into r[n:]
            r = r.xreplace(first.substitution(system))
            solved = [slot(M[i, j]) if i not in first.indices else sympy.Integer(int(i == j))
                      for i in range(n) for j in range(n)]
            rates = [slot(r[i]) if i not in first.indices else sympy.Integer(0) for i in range(n)]
            currents = [slot(v) for v in first.velocities]
            equations = block(targets + r_targets + [f"r[{n + k}]" for k in range(len(currents))],
                              [constants(e) for e in solved + rates + currents], "x", qs, guarded_angles,
                              plain=len(targets))
        mass_apart = mass_apart or first is not None or speeds is not None or system.implicit is not None
        mass = block(targets, exprs, "x", qs) if mass_apart else equations.part(set(targets))
        velocity_terms = forces = Block((), ())
        if terms_apart:
            velocity_terms = block([f"h[{i}]" for i in range(n)], [slot(e) for e in velocity_terms_of], "x", qs)
            forces = block([f"f[{i}]" for i in range(n)], [slot(e) for e in forces_of], "x", qs)
        if speeds is not None:  # qdot = C(q) u
            kinematics = block([f"xd[{i}]" for i in range(len(qs))], [constants(slot(e)) for e in speeds.kinematics],
                               "x", qs)

        qd = list(system.velocities)
        dTdq = []
        depends = [[M[i, j].free_symbols for j in range(n)] for i in range(n)]
        derivatives: dict = {}  # (entry, q): the symmetric entries are differentiated once
        for k, qk in enumerate(system.coordinates if speeds is None and canonical else ()):
            terms = []  # summed at once: a sum grown term by term is rebuilt n^2 times
            for i in range(n):
                for j in range(n):
                    if qk not in depends[i][j]:
                        continue
                    d = derivatives.get((M[i, j], qk))
                    if d is None:
                        d = derivatives[M[i, j], qk] = derivative(M[i, j], qk)
                    if d != 0:
                        terms.append(d * qd[i] * qd[j] / 2)
            dTdq.append(sympy.Add(*terms, system.forces[k]))
        if timed and canonical:  # hbar is not Lagrange's operator on Mbar: dp/dt = fbar - hbar + (dMbar/dq^i qdot^i) qdot
            dTdq = [system.forces[k] - system.velocity_terms[k]
                    + sum((derivative(M[k, j], qi) * qd[i] * qd[j] for j in range(n)
                           for i, qi in enumerate(system.coordinates) if qi in depends[k][j]), sympy.Integer(0))
                    for k in range(n)]
        if speeds is not None:  # no canonical form in the speeds: Mbar udot is not dp/dt
            dTdq = [sympy.Integer(0)] * n
        canonical_block = Block((), ())
        if canonical:
            canonical_block = block(r_targets, [constants(slot(e)) for e in dTdq], "x", qs, guarded_angles)
        if jacobian and system.implicit is None and speeds is None:
            exact = block(*jacobian_block(system, first, lambda e: constants(slot(e))), "x", qs, guarded_angles)
    held = None  # before `prepare`: its parameter products are constants of pre[] too
    if speeds is not None and speeds.holonomic:
        held = held_code(system, lambda e: constants(slot(e)), lambda t, e: block(t, e, "x", qs))
    prepare = block(*constants.definitions(), "c")

    potential = block(["V"], [slot(system.potential_energy)], "x", qs) if energies else Block((), ())
    labels = sorted(system.points) if with_points else []
    pos_targets, pos_exprs, dims = [], [], []
    offset = 0
    for label in labels:
        coords = system.points[label]
        dims.append((label, len(coords)))
        for c in coords:
            pos_targets.append(f"out[{offset}]")
            pos_exprs.append(slot(c))
            offset += 1
    positions = block(pos_targets, pos_exprs, "x", qs)
    implicit = None
    if system.implicit is not None:
        implicit = implicit_code(system, slot, lambda t, e, c: block(t, e, "x", qs))
    if canonical and (system.implicit is not None or first is not None):
        canonical_block = block(r_targets, [sympy.Integer(0)] * n, "x", qs)  # unused: no canonical form here
    return NumericModel(
        name=system.name,
        source=source,
        coordinates=tuple(q.name for q in system.coordinates),
        parameters=tuple((p.name, _default(p.value), p.unit) for p in params),
        points=tuple(dims),
        mass=mass,
        velocity_terms=velocity_terms,
        forces=forces,
        equations=equations,
        canonical=canonical_block,
        prepare=prepare,
        n_pre=constants.count + (len(system.implicit.dependent) + 1 if system.implicit is not None else 0),
        potential=potential,
        positions=positions,
        energies=energies,
        with_points=with_points,
        implicit=implicit,
        timed=timed,
        first_order=first.indices if first is not None else (),
        jacobian=exact,
        speeds=tuple(u.name for u in velocities) if speeds is not None else (),
        kinematics=kinematics,
        held=held,
        projected=projected,
        frame=frame,
        velocities=tuple(system.name_of(v) for v in system.velocities),
        terms_apart=terms_apart,
        with_canonical=canonical,
        mass_apart=mass_apart,
    )


__all__ = ["BASIC_NODES", "GUARD", "NearAxis", "NumericModel", "EXPANDED_MULTIPLE", "identifier", "jacobian_block", "multiple_angle", "prepare", "settled"]
