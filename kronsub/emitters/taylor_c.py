"""A Taylor integrator generated as C for the model: the generator (the hand-written C around it
comes in a :class:`Skeleton` from ``kronsub/simulation/csrc/``; :mod:`kronsub.simulation.taylor_c`
compiles and runs it).

The tape of :mod:`.tape` (the equations (10') as elementary operations) is written out as C: Taylor coefficients per operation, filled order by order with the recurrences of automatic
differentiation, ``Mbar_0 x_k = r_k - sum_{j>=1} Mbar_j x_{k-j}`` solved by ``L D L^T`` of
``Mbar_0`` once per step, then ``q_{k+1} = qdot_k / (k+1)``, ``qdot_{k+1} = x_k / (k+1)``.

The order ``N = 2 ceil(ln(1/tol) / 4) + 4`` (:func:`order_for`) is a compile-time constant: one library per order
used. Operations on parameters and constants alone are computed once per call, and a product
with such a factor costs one multiplication per order instead of a convolution; the constant
factors are moved out of products and merged first (``2 (c a) b`` is ``(2 c) (a b)``: one
multiplication per order, :func:`_fold_factors`); ``1/D`` and ``1/k`` are multiplications. The
derivative ``k a_k`` a sine, cosine or exponential needs of an argument linear in the state is read
off the state's next derivative (``k q_k = qdot_{k-1}``: :meth:`TaylorEmitter.derivative`), not formed.
Small systems at low orders get every order written out: each convolution
``sum_j a_j b_{k-j}`` is its older part ``sum_{j=1}^{k-1}`` plus the terms of order ``k``, and the
older parts of all the convolutions are summed lane by lane, 4 lanes to a GNU C vector
(``csrc/taylor_lanes.h``: ``KA[j][q]``, ``KB[j][q]``, into which every order's coefficients are
stored as whole vectors; arrays of doubles and a loop the compiler vectorizes where there are no
such vectors, with the same numbers), the terms of order ``k`` added last (they wait for this
order); ``x_k`` for ``k >= 1`` is ``Mbar_0^-1`` (from ``L D L^T``, once per step) times the
right-hand side, a short chain instead of two substitutions; the step's increment is evaluated
by Estrin's scheme. Otherwise the orders are one loop (much quicker to compile) with the same
split: at its top ``ks_lanes`` sums the older parts of every lane at once, each order stores its
coefficients into the lanes at its end, and a coefficient only its own order reads is a scalar of
the loop body (1.8x quicker than a convolution per product on the 10-link chain). The step is
``h = rho tol^(1/(N-1)) exp(-0.7 / (N - 1))``, ``rho = min_{k = N-1, N} (max(1, |y|) / |y_k|)^(1/k)``:
Jorba and Zou's ``rho / e^2 exp(-0.7 / (N - 1))`` (heyoka's) when ``tol = e^(-2 (N - 1))``, and
at the higher orders :func:`order_for` takes a longer step that still keeps ``(h / rho)^(N-1)``
below ``tol``. Jorba and Zou (and heyoka) read ``rho`` off the last two orders, which sees the
zero odd or even coefficients of a motion from rest. Orders ``N-3`` and ``N-2`` guard it: a
series can have two zero coefficients in a row (two rods released from rest level with their
hinge: every third and fourth), and the last two orders then read a radius 10x too long. So
``rho`` is the smallest read off orders ``N-3 .. N`` (:data:`GUARD`); those of ``N-3`` and ``N-2``
take ``log2 |y_k|`` from the bits of ``|y_k|`` alone (exponent plus mantissa, within 0.09, so
their radius is within 0.5 %), which costs a few integer operations per step. ``L D L^T``
multiplies by ``1/D`` rather than dividing. The states at the
requested output times come from the step's polynomial (dense output at no extra evaluation).
No libm call lies on the chain from step to step: the root is taken in log2 (inline, from the
bits of a double: ``csrc/taylor_step_root.h``), and order 0's sines and cosines come from the last
step's by angle addition (:func:`rotate_helper`), libm's every 32nd step, for a large
increment, and at tol < 1e-13 (where ``pow`` is also kept). Python calls ``ks_taylor_io``, whose
one argument holds every input and output.
The state and the time are compensated sums ``y + ylo``, ``t + tlo`` (issue 9, section 3): a step
adds its increment ``sum_{k>=1} y_k h^k`` and keeps that addition's rounding exactly (TwoSum);
at tol < 1e-13 the low part enters the next step to first order together with order 0's own
roundings (each rule's change at order 0 plus the exact error of each addition and product,
then ``dx = Mbar_0^-1 (dr - dM x_0 + r_0 - Mbar_0 x_0)``), so neither the ~500 roundings of the
state to eps ``|y|`` nor those of order 0 limit the result: the float64 floor of the benchmark.
Parameters stay run-time inputs. Plain C99 with libc and libm, in ``double``; no allocation per
step (large systems allocate their coefficients once per call). Systems with implicit
constraints are refused (:class:`TaylorUnavailable`).
"""
from __future__ import annotations

import functools
import math
import re
from dataclasses import dataclass

import mpmath
import sympy

from ..core.known_system import KnownSystem
from ..errors import KronsubError
from .escape import c_comment
from .tape import Tape, Unsupported

__all__ = ["GUARD", "MAX_ORDER", "MIN_ORDER", "Skeleton", "TaylorEmitter", "TaylorUnavailable", "UNROLL_TERMS", "WRITTEN_VECTORS",
           "emit_taylor_c", "order_for", "rotate_helper"]


@dataclass(frozen=True)
class Skeleton:
    """The hand-written C around the generated code (``kronsub/simulation/csrc/taylor*``): the
    integrator's ``str.format`` template (``{{ }}`` are C's braces), the step's root in log2 from
    the bits of a double, ``ks_rotate``'s template, and the helpers of the orders written out
    (lanes, 4 to a GNU C vector) and written as one loop."""

    template: str
    step_root: str
    rotate: str
    lanes: str
    loop: str


MIN_ORDER, MAX_ORDER = 4, 40


UNROLL_TERMS = 12_000  # write every order out while products + statements stay below this (gcc's time)


WRITTEN_VECTORS = 4  # lane sums written out vector by vector up to this (System I's 3), else a loop (3-link chain's 7)


GUARD = 2  # orders N-1-GUARD .. N-2 also give the step's radius: a series with gaps (see above)


_INTEGRALS = {"atan": "atan", "asin": "asin", "acos": "acos"}


class TaylorUnavailable(KronsubError):
    """A system the generated Taylor integrator cannot integrate."""


@functools.lru_cache(maxsize=256)
def order_for(tol: float) -> int:
    """The order ``2 ceil(ln(1/tol) / 4) + 4``, within ``[MIN_ORDER, MAX_ORDER]``: Jorba and
    Zou's ``ln(1/tol) / 2 + 1``, the optimum when a step costs ``N^2``, raised by 3 or 4 to an even
    order. The generated step costs about ``a + b N`` (the older products are summed lane by
    lane, off the chain from order to order), which favours a higher order with longer steps;
    odd orders measured slower at equal error (``benchmarks/HISTORY.md``)."""
    if not (tol > 0 and math.isfinite(tol)):
        raise ValueError(f"the tolerance must be a positive number (got {tol!r})")
    return min(MAX_ORDER, max(MIN_ORDER, 2 * math.ceil(-0.25 * math.log(tol)) + 4))


def _order_locals(arrays: list[str], kept: set[str], before: list[str], body: list[str]) -> list[str]:
    """The arrays of the loop form whose coefficient ``k`` can be a scalar of the loop body: read at
    ``k`` in the body (a value only written stays an entry), at no index but ``k`` and ``0``
    anywhere (``before``: order 0 and what follows it), and not ``kept`` (the lanes' and the state's,
    read at other orders)."""
    access = re.compile(r"\b(\w+)\[([^\]]+)\]")
    indices: dict[str, set[str]] = {}
    for line in before + body:
        for name, index in access.findall(line):
            indices.setdefault(name, set()).add(index)
    read = set()
    for line in body:
        for statement in line.rstrip(";").split("; "):
            target, op, expr = re.match(r"(\w+(?:\[[^\]]*\])?) ([-+*]?=) (.*)", statement).groups()
            read |= {name for name, index in access.findall(expr + (" " + target if op != "=" else "")) if index == "k"}
    return sorted((x for x in arrays if x not in kept and x in read and indices.get(x, set()) <= {"k", "0"}),
                  key=lambda x: (re.sub(r"\d", "", x), x))


def _ldl_substitution(n: int, x) -> list[str]:
    """``x`` <- ``Mbar^-1 x`` by the factors ``L`` (``L{a}_{b}``) and ``1/D`` (``R{a}``) of
    ``Mbar = L D L^T``: forward substitution, scaling, back substitution; ``x(a)`` names entry a."""
    lines = [f"{x(a)} -= L{a}_{b} * {x(b)};" for a in range(n) for b in range(a)]
    lines += [f"{x(a)} *= R{a};" for a in range(n)]
    return lines + [f"{x(a)} -= L{b}_{a} * {x(b)};" for a in reversed(range(n)) for b in range(a + 1, n)]


def _ldl_inverse(n: int) -> list[str]:
    """``A{a}_{b}`` (a >= b) <- ``Mbar^-1 = L^-T D^-1 L^-1`` from ``L{a}_{b}`` and ``R{a}``, a column
    at a time as :func:`_ldl_substitution` solves for ``e_b`` (its known zeros and ones left out)."""
    lines = []
    for b in range(n):
        for a in range(b + 1, n):
            lines.append(f"A{a}_{b} = -(" + " + ".join([f"L{a}_{b}"] + [f"L{a}_{c} * A{c}_{b}" for c in range(b + 1, a)])
                         + ");")
        lines.append(f"A{b}_{b} = R{b};")
        lines += [f"A{a}_{b} *= R{a};" for a in range(b + 1, n)]
        lines += [f"A{a}_{b} -= " + " + ".join(f"L{c}_{a} * A{c}_{b}" for c in range(a + 1, n)) + ";"
                  for a in reversed(range(b, n - 1))]
    return lines


def _literal(value) -> str:
    with mpmath.workdps(40):
        text = mpmath.nstr(mpmath.mpf(value), 36, min_fixed=-1, max_fixed=1, strip_zeros=False)
    return text if ("." in text or "e" in text) else text + ".0"


def _sum_errors(terms: list[str]) -> list[str]:
    """The exact rounding errors of ``terms[0] + terms[1] + ...`` summed left to right (C's order)."""
    errors, partial = [], terms[0]
    for term in terms[1:]:
        errors.append(f"ks_sum_error({partial}, {term})")
        partial = f"({partial} + {term})"
    return errors or ["0.0"]


def _tree(terms: list[str]) -> str:
    """``terms`` summed pairwise: ``((a + b) + (c + d))``, a short dependency chain."""
    if not terms:
        return "0.0"
    while len(terms) > 1:
        terms = [f"({terms[i]} + {terms[i + 1]})" if i + 1 < len(terms) else terms[i]
                 for i in range(0, len(terms), 2)]
    return terms[0]


def _estrin(terms: list[str], powers) -> str:
    """``terms[0] + terms[1] x + terms[2] x^2 + ...`` by Estrin's scheme, ``powers`` naming ``x``,
    ``x^2``, ``x^4``, ...: pairs joined level by level, a chain of log2(len(terms)) products."""
    for x in powers:
        terms = [f"({terms[i]} + {terms[i + 1]} * {x})" if i + 1 < len(terms) else terms[i]
                 for i in range(0, len(terms), 2)]
    assert len(terms) == 1
    return terms[0]


def _last(old: list[str], new: list[str]) -> str:
    """``old`` summed pairwise, then each of ``new`` added: the terms that wait for this order's
    coefficients enter last, so only one addition each lies on the chain from order to order."""
    text = _tree(old) if old else ""
    for term in new:
        text = f"({text} + {term})" if text else term
    return text or "0.0"


def _varying(nodes) -> list[bool]:
    """Does node i vary along the trajectory (else: parameters and constants only)."""
    var = []
    for kind, args, _ in nodes:
        var.append(kind in ("state", "time") or (kind not in ("const", "param") and any(var[a] for a in args)))
    return var


def _fold_factors(nodes, roots: list[int]) -> tuple[list, list[int]]:
    """The tape with its constant factors moved outward and merged: ``s (c a)``, ``(c a) b`` and
    ``c (c' a)`` become one product ``(s c c') (a b)`` with its factor computed once per call, so
    each order pays one multiplication for it instead of one per factor (exact when the factors
    are powers of two, as ``2``, ``-1``). Returns the new nodes (topological) and the roots' nodes."""
    var = _varying(nodes)
    new: list = []
    index: dict = {}

    def add(kind, args, data=None) -> int:
        key = (kind, tuple(args), data)
        if key not in index:
            new.append(key)
            index[key] = len(new) - 1
        return index[key]

    memo: dict[int, tuple] = {}  # old node -> (literal, constant nodes, new node): the value is their product

    def visit(i: int) -> tuple:
        if i in memo:
            return memo[i]
        kind, args, data = nodes[i]
        lit, consts, base = mpmath.mpf(1), (), None
        if not var[i] or kind in ("state", "time"):
            base = add(kind, [materialize(a) for a in args], data)
        elif kind == "scale":
            lit0, consts, base = visit(args[0])
            lit = lit0 * data
        elif kind == "mul":
            x, y = args
            if not var[x] or not var[y]:
                c, v = (x, y) if not var[x] else (y, x)
                lit, consts0, base = visit(v)
                consts = tuple(sorted(consts0 + (materialize(c),)))
            else:
                lx, cx, bx = visit(x)
                ly, cy, by = visit(y)
                lit, consts, base = lx * ly, tuple(sorted(cx + cy)), add("mul", sorted((bx, by)))
        else:
            base = add(kind, [materialize(a) for a in args], data)
        memo[i] = (lit, consts, base)
        return memo[i]

    def materialize(i: int) -> int:
        lit, consts, base = visit(i)
        if not consts:
            return base if lit == 1 else add("scale", (base,), lit)
        factor = consts[0]
        for c in consts[1:]:
            factor = add("mul", (factor, c))
        if lit != 1:
            factor = add("scale", (factor,), lit)
        return add("mul", (factor, base))

    out = [materialize(r) for r in roots]
    return new, out


class TaylorEmitter:
    """The C of one system at one order."""

    def __init__(self, system: KnownSystem, order: int):
        if system.implicit is not None:
            raise TaylorUnavailable("method 'taylor' needs explicit equations (its Taylor series), which a system "
                                    "with implicit constraints does not have\n  hint: use dop853 (default), gauss4, "
                                    "Radau or LSODA")
        self.n = n = len(system.coordinates)
        self.N = order
        self.nparam = len(system.parameters)
        tape = Tape([*system.coordinates, *system.velocities], {}, tuple(p.symbol for p in system.parameters))
        M, r = system.mass_matrix, system.forces - system.velocity_terms
        try:
            M = [tape.node(sympy.sympify(M[a, b])) for a in range(n) for b in range(n)]
            r = [tape.node(sympy.sympify(r[a])) for a in range(n)]
        except Unsupported as exc:
            raise TaylorUnavailable(str(exc).replace("the high-precision reference", "method 'taylor'")) from None
        states = [i for i, (kind, _, _) in enumerate(tape.nodes) if kind == "state"]  # kept, in their order
        self.nodes, roots = _fold_factors(tape.nodes, states + M + r)
        roots = roots[len(states):]
        self.M = [roots[a * n:(a + 1) * n] for a in range(n)]
        self.r = roots[n * n:]
        self.var = _varying(self.nodes)  # does node i vary along the trajectory (else: parameters and constants)
        self.needed = set()  # the nodes Mbar and fbar - hbar depend on
        stack = [x for row in self.M for x in row] + list(self.r)
        while stack:
            i = stack.pop()
            if i not in self.needed:
                self.needed.add(i)
                stack.extend(self.nodes[i][1])
        # derivative arrays d_j = j a_j of the nodes whose recurrences need them
        self.pairs: dict[tuple[str, str], int] = {}  # (a, b) of each sum_j a_j b_{k-j}: its lane
        self.scaled = set()
        for i, (kind, args, _) in enumerate(self.nodes):
            if kind in ("sincos", "exp", "integral", "pow") and self.var[args[0]] and i in self.needed:
                self.scaled.add(args[0])
        terms = sum(1 for kind, args, _ in self.nodes if kind in ("mul", "sincos", "exp", "log", "pow", "integral")
                    and self.var[args[0]]) + sum(1 for row in self.M for x in row if self.var[x])
        statements = sum(1 for i in self.needed if self.var[i]) * order
        self.unrolled = terms * order * order // 2 + statements <= UNROLL_TERMS

    # names -------------------------------------------------------------------------------

    def name(self, i: int) -> str:
        kind, args, data = self.nodes[i]
        if kind == "state":
            return f"Y{data}"
        if kind in ("sin", "cos"):
            return f"{kind[0].upper()}{args[0]}"
        return f"v{i}"

    def at(self, i: int, k) -> str:
        """Coefficient ``k`` of node ``i`` (a constant node has only coefficient 0)."""
        if not self.var[i]:
            return f"c{i}" if k == 0 else "0.0"
        return f"{self.name(i)}[{k}]"

    def conv(self, a: str, b: str, lo, hi, k) -> str:
        """``sum_{j=lo}^{hi} a[j] b[k-j]`` (``k`` an int, or the loop variable "k"; ``hi`` is ``k`` or
        ``k - 1``): its older part ``sum_{j=1}^{k-1}`` from the lanes (``KS``, all the lanes summed at
        once), then the terms with a coefficient of order ``k``, last: the chain from order to order."""
        assert lo in (0, 1) and hi in ((k - 1, k) if isinstance(k, int) else ("k - 1", k))
        new = ([f"{a}[0] * {b}[{k}]"] if lo == 0 else []) + ([f"{a}[{k}] * {b}[0]"] if hi == k else [])
        if a == b and len(new) == 2:  # a square: a_0 a_k twice, exactly 2 (a_0 a_k)
            new = [f"2.0 * {a}[0] * {a}[{k}]"]
        if isinstance(k, int) and k < 2:
            return _last([], new)
        lane = self.pairs.setdefault((a, b), len(self.pairs))
        return _last([f"KS_LANE({lane})" if self.unrolled else f"KS[{lane}]"], new)

    def derivative(self, i: int, k) -> str | None:
        """``k a_k`` (the coefficient ``k - 1`` of ``a'``) of node ``i`` when ``a`` is linear in the
        state: read off the state's next derivative (``k q_k = qdot_{k-1}``, ``k qdot_k = x_{k-1}``),
        which takes two roundings and a multiplication per order off the chain; else None."""
        kind, args, data = self.nodes[i]
        km1 = k - 1 if isinstance(k, int) else "k - 1"
        if kind == "state":
            return f"Y{data + self.n}[{km1}]" if data < self.n else f"X{data - self.n}[{km1}]"
        if kind == "scale":
            inner = self.derivative(args[0], k)
            return None if inner is None else f"{_literal(data)} * {inner}"
        if kind == "mul" and not (self.var[args[0]] and self.var[args[1]]):
            c, v = (args[0], args[1]) if not self.var[args[0]] else (args[1], args[0])
            inner = self.derivative(v, k)
            return None if inner is None else f"c{c} * {inner}"
        if kind == "add":
            terms = [self.derivative(x, k) for x in args if self.var[x]]
            return None if None in terms else " + ".join(terms)
        return None

    # one coefficient of one node ---------------------------------------------------------

    def coefficient(self, i: int, k) -> list[str]:
        """C statements computing coefficient ``k >= 1`` (an int, or the loop variable "k")."""
        kind, args, data = self.nodes[i]
        v = self.name(i)
        a = self.name(args[0]) if args else ""
        inv_k = _literal(mpmath.mpf(1) / k) if isinstance(k, int) else "ks_inv[k]"
        km1 = k - 1 if isinstance(k, int) else "k - 1"
        if kind in ("state", "sin", "cos"):
            return []
        if kind == "time":
            return [f"{v}[{k}] = {k} == 1 ? 1.0 : 0.0;"]
        if kind == "add":
            return [f"{v}[{k}] = " + " + ".join(self.at(x, k) for x in args if self.var[x]) + ";"]
        if kind == "scale":
            return [f"{v}[{k}] = {_literal(data)} * {a}[{k}];"]
        if kind == "mul":
            x, y = args
            if not self.var[x] or not self.var[y]:
                c, s = (x, y) if not self.var[x] else (y, x)
                return [f"{v}[{k}] = c{c} * {self.name(s)}[{k}];"]
            b = self.name(y)
            return [f"{v}[{k}] = {self.conv(a, b, 0, k, k)};"]
        d = f"d{args[0]}" if args else ""
        if kind == "sincos":
            return [f"S{i}[{k}] = {inv_k} * ({self.conv(d, f'C{i}', 1, k, k)});",
                    f"C{i}[{k}] = -{inv_k} * ({self.conv(d, f'S{i}', 1, k, k)});"]
        if kind == "exp":
            return [f"{v}[{k}] = {inv_k} * ({self.conv(d, v, 1, k, k)});"]
        if kind == "log":  # a v' = a'
            return [f"{v}[{k}] = ({a}[{k}] - {inv_k} * ({self.conv(f'd{i}', a, 1, km1, k)})) / {a}[0];"]
        if kind == "pow":  # a v' = p v a': sum_j ((p+1) j - k) a_j v_{k-j} / (k a_0)
            p1 = _literal(mpmath.mpf(data) + 1)
            return [f"{v}[{k}] = ({p1} * ({self.conv(d, v, 1, k, k)}) - {k} * ({self.conv(a, v, 1, k, k)}))"
                    f" * {inv_k} / {a}[0];"]
        if kind == "integral":  # v' = g(a) a'
            g = args[1]
            if not self.var[g]:
                return [f"{v}[{k}] = c{g} * {a}[{k}];"]
            return [f"{v}[{k}] = {inv_k} * ({self.conv(d, self.name(g), 1, k, k)});"]
        if kind == "abs":
            return [f"{v}[{k}] = {a}[0] >= 0 ? {a}[{k}] : -{a}[{k}];"]
        if kind == "sign":
            return [f"{v}[{k}] = 0.0;"]
        raise AssertionError(kind)

    def first(self, i: int, target: str) -> list[str]:
        """C statements computing coefficient 0 of node ``i`` (into ``c{i}`` or ``v{i}[0]``)."""
        kind, args, data = self.nodes[i]
        out = f"c{i}" if target == "c" else f"{self.name(i)}[0]"
        a = self.at(args[0], 0) if args else ""
        if kind in ("sin", "cos") and target == "c":
            return [f"c{i} = {kind[0]}{args[0]};"]
        if kind in ("state", "sin", "cos"):
            return []
        if kind == "const":
            return [f"c{i} = {_literal(data)};"]
        if kind == "param":
            return [f"c{i} = param[{data}];"]
        if kind == "time":
            return [f"{out} = t + tlo;"]
        if kind == "add":
            return [f"{out} = " + " + ".join(self.at(x, 0) for x in args) + ";"]
        if kind == "scale":
            return [f"{out} = {_literal(data)} * {a};"]
        if kind == "mul":
            return [f"{out} = {a} * {self.at(args[1], 0)};"]
        if kind == "sincos":
            if target == "c":
                return [f"s{i} = sin({a}); c{i} = cos({a});"]
            return [f"ks_rotate({a}, R{i}, fresh); S{i}[0] = R{i}[1]; C{i}[0] = R{i}[2];"]
        if kind == "exp":
            return [f"{out} = exp({a});"]
        if kind == "log":
            return [f"{out} = log({a});"]
        if kind == "pow":
            return [f"{out} = pow({a}, {_literal(data)});"]
        if kind == "integral":
            return [f"{out} = {_INTEGRALS[data]}({a});"]
        if kind == "abs":
            return [f"{out} = fabs({a});"]
        if kind == "sign":
            return [f"{out} = ({a} > 0) - ({a} < 0);"]
        raise AssertionError(kind)

    def lo(self, i: int):
        """The C name of node ``i``'s first-order change under the state's low part, or None (constant)."""
        kind, args, data = self.nodes[i]
        if not self.var[i]:
            return None
        if kind == "state":
            return f"ylo[{data}]"
        if kind == "time":
            return "tlo"
        if kind in ("sin", "cos"):
            return f"e{kind[0].upper()}{args[0]}"
        return f"e{i}"

    def tangent(self, i: int) -> list[str]:
        """C statements of node ``i``'s change to first order in ``(ylo, tlo)`` at order 0: the
        low parts the coefficients (evaluated at the high parts) leave out."""
        kind, args, data = self.nodes[i]
        e = self.lo(i)
        a0 = self.at(args[0], 0) if args else ""
        ea = self.lo(args[0]) if args else None
        if kind in ("state", "time", "sin", "cos"):
            return []
        if kind == "add":  # and the rounding of each addition, exactly (TwoSum)
            terms = [self.lo(x) for x in args if self.var[x]] + _sum_errors([self.at(x, 0) for x in args])
            return [f"{e} = {' + '.join(terms)};"]
        if kind == "mul":  # and the rounding of the product, exactly (Dekker)
            x, y = args
            terms = [f"{self.at(x, 0)} * {self.lo(y)}" if self.var[y] else None,
                     f"{self.lo(x)} * {self.at(y, 0)}" if self.var[x] else None,
                     f"ks_mul_error({self.at(x, 0)}, {self.at(y, 0)})"]
            return [f"{e} = {' + '.join(t for t in terms if t)};"]
        if kind == "scale":
            return [f"{e} = {_literal(data)} * {ea} + ks_mul_error({_literal(data)}, {a0});"]
        if kind == "sincos":
            return [f"eS{i} = C{i}[0] * {ea};", f"eC{i} = -S{i}[0] * {ea};"]
        if kind == "exp":
            return [f"{e} = {self.at(i, 0)} * {ea};"]
        if kind == "log":
            return [f"{e} = {ea} / {a0};"]
        if kind == "pow":
            return [f"{e} = {a0} != 0 ? {_literal(data)} * {self.at(i, 0)} / {a0} * {ea} : 0.0;"]
        if kind == "integral":
            return [f"{e} = {self.at(args[1], 0)} * {ea};"]
        if kind == "abs":
            return [f"{e} = {a0} >= 0 ? {ea} : -{ea};"]
        if kind == "sign":
            return [f"{e} = 0.0;"]
        raise AssertionError(kind)

    # the whole file ----------------------------------------------------------------------

    def source(self, name: str, skeleton: Skeleton) -> str:
        n, N, nodes = self.n, self.N, self.nodes
        consts, arrays = [], []
        for i, (kind, args, _) in enumerate(nodes):
            if kind == "state" or (kind in ("sin", "cos") and self.var[i]) or i not in self.needed:
                continue
            if not self.var[i]:
                consts += [f"s{i}", f"c{i}"] if kind == "sincos" else [f"c{i}"]
            elif kind == "sincos":
                arrays += [f"S{i}", f"C{i}"]
            else:
                arrays.append(f"v{i}")
        arrays += [f"d{i}" for i in sorted(self.scaled | {i for i, (kind, _, _) in enumerate(nodes)
                                                          if kind == "log" and self.var[i] and i in self.needed})]
        arrays += [f"Y{j}" for j in range(2 * n)] + [f"X{a}" for a in range(n)] + [f"B{a}" for a in range(n)]
        prologue = []
        for i, (kind, args, data) in enumerate(nodes):
            if not self.var[i] and i in self.needed:
                prologue += self.first(i, "c")
        step = []  # order 0, then 1 .. N - 1

        def emit_order(k) -> list[str]:
            lines = []
            for i in range(len(nodes)):
                if not self.var[i] or i not in self.needed:
                    continue
                lines += self.first(i, "v") if k == 0 else self.coefficient(i, k)
                if i in self.scaled or nodes[i][0] == "log":
                    lines.append(f"d{i}[{k}] = {self.derivative(i, k) or f'{k} * {self.name(i)}[{k}]'};" if k != 0
                                 else f"d{i}[0] = 0.0;")
            return lines

        def solve(k) -> list[str]:
            lines, inverse = [], self.unrolled and k != 0
            if k == 0:  # Mbar_0 = L D L^T, L unit lower triangular
                for a in range(n):
                    for b in range(a + 1):
                        s = " - ".join([self.at(self.M[a][b], 0)] + [f"L{a}_{j} * L{b}_{j} * D{j}" for j in range(b)])
                        if a == b:
                            lines.append(f"D{a} = {s};")
                            lines.append(f"if (!(D{a} > 0)) {{ status = 1; goto done; }}")
                            lines.append(f"R{a} = 1.0 / D{a};")
                        else:
                            lines.append(f"L{a}_{b} = ({s}) * R{b};")
            for a in range(n):  # r_k - sum_{j>=1} Mbar_j x_{k-j}
                terms = [self.at(self.r[a], k)] if (k == 0 or self.var[self.r[a]]) else ["0.0"]
                for b in range(n):
                    m = self.M[a][b]
                    if self.var[m] and k != 0:
                        terms.append(f"({self.conv(self.name(m), f'X{b}', 1, k, k)})")
                lines.append(f"{'B' if inverse else 'X'}{a}[{k}] = {' - '.join(terms)};")
            if k == 0 and self.unrolled:
                lines += _ldl_inverse(n)
            if inverse:  # x_k = Mbar_0^-1 (r_k - ...): a product (a short chain), not two substitutions
                lines += [f"X{a}[{k}] = " + _tree([f"A{max(a, b)}_{min(a, b)} * B{b}[{k}]" for b in range(n)]) + ";"
                          for a in range(n)]
            else:
                lines += _ldl_substitution(n, lambda a: f"X{a}[{k}]")
            inv = _literal(mpmath.mpf(1) / (k + 1)) if isinstance(k, int) else "ks_inv[k + 1]"
            k1 = k + 1 if isinstance(k, int) else "k + 1"
            for a in range(n):
                lines.append(f"Y{a}[{k1}] = {inv} * Y{n + a}[{k}]; Y{n + a}[{k1}] = {inv} * X{a}[{k}];")
            return lines

        # (Mbar_0 + dM)(x_0 + dx) = r_0 + dr to first order in the low parts: dx = Mbar_0^-1 (dr - dM x_0)
        lows = []
        for i in range(len(nodes)):
            if self.var[i] and i in self.needed:
                lows += self.tangent(i)
        for a in range(n):
            # and the residual r_0 - Mbar_0 x_0 of the rounded solution, its roundings kept exactly
            products = [f"{self.at(self.M[a][b], 0)} * X{b}[0]" for b in range(n)]
            chain = [self.at(self.r[a], 0)] + [f"-({x})" for x in products]
            residual = " + ".join(chain) + " + " + " + ".join(_sum_errors(chain)) + " - " + " - ".join(
                f"ks_mul_error({self.at(self.M[a][b], 0)}, X{b}[0])" for b in range(n))
            terms = [self.lo(self.r[a]) or "0.0"] + [f"{self.lo(self.M[a][b])} * X{b}[0]"
                                                    for b in range(n) if self.var[self.M[a][b]]]
            lows.append(f"EX{a} = {' - '.join(terms)} + ({residual});")
        lows += _ldl_substitution(n, lambda a: f"EX{a}")
        lo_name = re.compile(r"\b(?:e\d+|eS\d+|eC\d+)\b")
        while True:  # only the changes something reads
            read = {x for line in lows for x in lo_name.findall(line.split("=", 1)[1])}
            kept = [line for line in lows if not lo_name.fullmatch(line.split(" ", 1)[0])
                    or line.split(" ", 1)[0] in read]
            if len(kept) == len(lows):
                break
            lows = kept
        step += emit_order(0) + solve(0) + ["if (fine) {"] + ["    " + x for x in lows] + ["}"]
        if self.unrolled:
            orders = [emit_order(k) + solve(k) for k in range(1, N)]  # the lanes are known after this
            vectors = -(-len(self.pairs) // 4)  # of 4 lanes: KA[k][q] is lanes 4q .. 4q + 3 of order k
            lanes = 4 * vectors
            pairs = list(self.pairs) + [("0.0", "0.0")] * (lanes - len(self.pairs))

            def row(side: int, q: int, k: int) -> str:  # lanes 4q .. 4q + 3 of order k, padded with zeros
                names = (pair[side] for pair in pairs[4 * q:4 * q + 4])
                return ", ".join(x if x == "0.0" else f"{x}[{k}]" for x in names)

            for k, lines in enumerate(orders, 1):
                if k >= 2 and self.pairs:  # the sums over older coefficients, 4 lanes per vector operation
                    terms = _last([f"KA[{j}][p] * KB[{k - j}][p]" for j in range(2, k - 1)],  # the last order's last
                                  [f"KA[{j}][p] * KB[{k - j}][p]" for j in sorted({1, k - 1})])
                    vector = (" ".join(f"KS[{q}] = {terms.replace('[p]', f'[{q}]')};" for q in range(vectors))
                              if vectors <= WRITTEN_VECTORS else f"for (p = 0; p < {vectors}; ++p) KS[p] = {terms};")
                    step += ["#if KS_VECTOR", vector,
                             "#else", f"for (p = 0; p < {lanes}; ++p) KS[p] = {terms};", "#endif"]
                step += lines
                if k <= N - 2:  # this order's coefficients into the lanes they are read in: whole vectors, which
                    step.append("#if KS_VECTOR")  # a vector load takes straight from the store
                    step += [f"KA[{k}][{q}] = KS_V4({row(0, q, k)}); KB[{k}][{q}] = KS_V4({row(1, q, k)});"
                             for q in range(vectors)]
                    step.append("#else")
                    step += [f"KA[{k}][{lane}] = {a}[{k}]; KB[{k}][{lane}] = {b}[{k}];"
                             for (a, b), lane in self.pairs.items()]
                    step.append("#endif")
            if self.pairs:
                storage_lanes = ["#if KS_VECTOR",
                                 f"ks_v4 KA[TN_ORDER][{vectors}], KB[TN_ORDER][{vectors}], KS[{vectors}];", "#else",
                                 f"double KA[TN_ORDER][{lanes}], KB[TN_ORDER][{lanes}], KS[{lanes}];", "#endif",
                                 "int p;"]
        else:  # one loop over the orders: the lanes' older sums, this order's terms, its lanes stored
            body = emit_order("k") + solve("k")  # the lanes are known after this
            lanes = max(4, -(-len(self.pairs) // 4) * 4)
            stores = [f"KA[k * TN_LANES + {lane}] = {a}[k]; KB[k * TN_LANES + {lane}] = {b}[k];"
                      for (a, b), lane in self.pairs.items()]
            local = _order_locals(arrays, {x for pair in self.pairs for x in pair} | {f"Y{j}" for j in range(2 * n)},
                                  step, body)
            if local:  # no store and reload of them on the chain within the order
                ordered = re.compile(r"\b(" + "|".join(local) + r")\[k\]")
                body = [f"double {', '.join(f'{x}_k' for x in local)};"] + \
                    [ordered.sub(lambda m: f"{m[1]}_k", line) for line in body]
            step.append("for (k = 1; k < TN_ORDER; ++k) {")
            step += ["    " + x for x in ["ks_lanes(KS, KA, KB, k);", *body, *stores]]
            step.append("}")
        ldl = [f"L{a}_{b}" for a in range(n) for b in range(a)] + [f"D{a}" for a in range(n)] + \
            [f"R{a}" for a in range(n)]  # R = 1 / D: no division on the chain from order to order
        if self.unrolled:
            ldl += [f"A{a}_{b}" for a in range(n) for b in range(a + 1)]
        lo_names = sorted(set(re.findall(r"\b(?:e\d+|eS\d+|eC\d+|EX\d+)\b", "\n".join(lows))),
                          key=lambda x: (re.sub(r"\d", "", x), int(re.sub(r"\D", "", x))))
        decl = ["double " + ", ".join(f"{x} = 0" for x in lo_names) + ";"]
        rotated = [i for i, (kind, _, _) in enumerate(nodes) if kind == "sincos" and self.var[i] and i in self.needed]
        if rotated:  # each varying sine and cosine at order 0: {a_old, sin, cos} from the last step
            decl.append("double " + ", ".join(f"R{i}[3] = {{0, 0, 0}}" for i in rotated) + ";")
        if consts:
            decl.append("double " + ", ".join(consts) + ";")
        if ldl:
            decl.append("double " + ", ".join(f"{x} = 0" for x in ldl) + ";")
        ny = 2 * n
        if self.unrolled:  # every coefficient a scalar Y0_3 (registers, no store-to-load chains)
            pattern = re.compile(r"\b(" + "|".join(arrays) + r")\[(\d+)\]")
            step = [pattern.sub(lambda m: f"{m[1]}_{m[2]}", line) for line in step]
            used = set(re.findall(r"\b(?:" + "|".join(arrays) + r")_\d+\b", "\n".join(step)))
            scalars = sorted(used | {f"Y{j}_{k}" for j in range(ny) for k in range(N + 1)},
                             key=lambda x: (x[0], [int(p) for p in re.findall(r"\d+", x)]))
            storage = ["double " + ", ".join(scalars) + ";"]
            zero = []
            if self.pairs:
                storage += storage_lanes
                zero += ["#if KS_VECTOR",
                         f"for (p = 0; p < {vectors}; ++p) {{ KS[p] = KS_V4(0.0, 0.0, 0.0, 0.0); "
                         "for (k = 0; k < TN_ORDER; ++k) KA[k][p] = KB[k][p] = KS[p]; }", "#else",
                         f"for (p = 0; p < {lanes}; ++p) {{ KS[p] = 0; for (k = 0; k < TN_ORDER; ++k) "
                         "KA[k][p] = KB[k][p] = 0; }", "#endif"]
            consts_void = scalars
            load = " ".join(f"Y{j}_0 = y[{j}];" for j in range(ny))
            sizes = "\n        ".join(f"if (!(fabs(Y{j}_{N - 1 + e}) <= size[{e}])) size[{e}] = fabs(Y{j}_{N - 1 + e});"
                                      for j in range(ny) for e in (0, 1))
            sizes += "".join(f"\n        guard[{e}] = ks_umax(guard[{e}], ks_abits(Y{j}_{N - 1 - GUARD + e}));"
                             for j in range(ny) for e in range(GUARD))

            def increment(tau: str, estrin: bool = True, count: int = ny) -> str:  # sum_{k>=1} Y_k tau^k, by Estrin or Horner
                # (of the first ``count`` components)
                # Estrin's scheme: Y_1 tau + (Y_2 + Y_3 tau + (Y_4 + Y_5 tau) tau^2 + ...) tau^2 in tau,
                # tau^2, tau^4, ...: a chain of log2(N) products, not N; the leading term added last
                powers = [tau, f"{tau}2"]  # as many as the N - 1 terms after the first need, at least tau^2
                while 2 ** len(powers) < N - 1:
                    powers.append(f"{tau}{2 ** len(powers)}")

                def poly(j):
                    if not estrin:
                        text = f"Y{j}_{N}"
                        for k in range(N - 1, 0, -1):
                            text = f"({text} * {tau} + Y{j}_{k})"
                        return f"{text} * {tau}"
                    return f"Y{j}_1 * {tau} + {_estrin([f'Y{j}_{k}' for k in range(2, N + 1)], powers)} * {tau}2"
                square = [f"{b} = {a} * {a};" for a, b in zip(powers, powers[1:])] if estrin else []
                lines = [f"double {', '.join(powers[1:])};", *square] if estrin else []
                return " ".join(["{", *lines, *(f"dy[{j}] = {poly(j)};" for j in range(count)), "}"])

            dense = increment("tau", estrin=False)  # Horner: the rows are off the chain from step to step
            dense_coordinates = increment("tau", estrin=False, count=n)
            advance = increment("h")
            helpers = skeleton.lanes if self.pairs else ""
        else:
            storage = ["double *W = calloc((size_t)" + str(len(arrays))
                       + " * (TN_ORDER + 1) + (2 * TN_ORDER + 1) * TN_LANES, sizeof(double));"]
            storage += [f"double *{x} = W + {j} * (TN_ORDER + 1);" for j, x in enumerate(arrays)]
            storage += [f"double *KA = W + {len(arrays)} * (TN_ORDER + 1), *KB = KA + TN_ORDER * TN_LANES, "
                        "*KS = KB + TN_ORDER * TN_LANES;"]
            storage += ["double *Y[TN_NY] = {" + ", ".join(f"Y{j}" for j in range(ny)) + "};"]
            zero = ["if (W == NULL) return 1;"]
            consts_void = arrays
            load = "for (i = 0; i < TN_NY; ++i) Y[i][0] = y[i];"
            sizes = ("for (i = 0; i < TN_NY; ++i) {\n"
                     "            if (!(fabs(Y[i][TN_ORDER - 1]) <= size[0])) size[0] = fabs(Y[i][TN_ORDER - 1]);\n"
                     "            if (!(fabs(Y[i][TN_ORDER]) <= size[1])) size[1] = fabs(Y[i][TN_ORDER]);\n"
                     + "".join(f"            guard[{e}] = ks_umax(guard[{e}], ks_abits(Y[i][TN_ORDER - {1 + GUARD - e}]));\n"
                               for e in range(GUARD))
                     + "        }")
            dense = "ks_horner(Y, tau, dy);"
            dense_coordinates = "ks_horner_coordinates(Y, tau, dy);"
            advance = "ks_horner(Y, h, dy);"
            inverses = ", ".join(["0.0"] + [_literal(mpmath.mpf(1) / k) for k in range(1, N + 2)])
            helpers = (f"\n#define TN_LANES {lanes}\n" + skeleton.loop
                       + "\nstatic const double ks_inv[TN_ORDER + 2] = {" + inverses + "};  /* 1 / k */\n")
        def first_order(v: str, velocities: bool = True) -> str:  # the low parts carried through the step to first order
            return " ".join(f"dy[{a}] += {v} * (ylo[{n + a}] + 0.5 * {v} * EX{a});"
                            + (f" dy[{n + a}] += {v} * EX{a};" if velocities else "") for a in range(n))

        dense += " if (fine) { " + first_order("tau") + " }"
        dense_coordinates += " if (fine) { " + first_order("tau", velocities=False) + " }"
        advance += " if (fine) { " + first_order("h") + " }"
        text = skeleton.template.format(
            name=c_comment(name), n=n, ny=ny, order=N, nparam=max(1, self.nparam),
            # the loop form calls them (gcc: a third less compile time for the 10-link chain, the
            # same speed); written out, they stay inline: the float64 end calls them every step
            outline="" if self.unrolled else "KS_OUTLINE ",
            outline_note="" if self.unrolled else (
                ";\n   called, not inlined: the order-0 tangents of a large system are long, and gcc's\n"
                "   register allocation over them took most of its time"),
            decl="\n    ".join(decl + storage), zero="\n    ".join(zero + [f"(void){x};" for x in consts_void + consts]),
            prologue="\n    ".join(prologue), helpers=helpers + (rotate_helper(skeleton.rotate) if rotated else ""), root=skeleton.step_root,
            fresh="const int fresh = fine || (steps & 31) == 0;" if rotated else "", load=load, sizes=sizes,
            guard_n=GUARD, guard_finite="".join(f" && guard[{e}] < KS_INF_BITS" for e in range(GUARD)),
            guard_any=" || ".join(f"guard[{e}] > 0" for e in range(GUARD)),
            guard_log="\n            ".join(
                f"double g{e} = guard[{e}] > 0 ? (ls - ks_log2_bits(guard[{e}])) * (1.0 / {N - 1 - GUARD + e}) : 1e300;"
                for e in range(GUARD)),
            guard_min="\n            ".join(f"if (g{e} < l) l = g{e};" for e in range(GUARD)),
            guard_fine="\n                ".join(
                f"if (guard[{e}] > 0 && (h < 0 || ls - ks_log2_bits(guard[{e}]) < lh * {N - 1 - GUARD + e})) {{ "
                f"double hk = factor * pow(scale / ks_double(guard[{e}]), 1.0 / {N - 1 - GUARD + e}); if (h < 0 || hk < h) h = hk; }}"
                for e in range(GUARD)),
            dense=dense, dense_coordinates=dense_coordinates, advance=advance, step="\n            ".join(step), free="free(W);" if not self.unrolled else "")
        return text


def rotate_helper(rotate: str) -> str:
    """``ks_rotate``: the sine and cosine at order 0 from the last step's by the angle-addition
    formula, the increment's by their series (``|d| <= 1/2``, truncation below 1e-21)."""
    with mpmath.workdps(40):
        sine = [_literal((-1) ** j / mpmath.factorial(2 * j + 1)) for j in range(9)]
        cosine = [_literal((-1) ** j / mpmath.factorial(2 * j)) for j in range(9)]
    powers = ("z", "z2", "z4", "z8")
    return rotate.format(sine=_estrin(sine, powers), cosine=_estrin(cosine, powers))


def emit_taylor_c(system: KnownSystem, order: int, skeleton: Skeleton) -> str:
    """The C source of ``ks_taylor`` of order ``order`` for ``system`` in ``skeleton`` (see the
    module docstring)."""
    return TaylorEmitter(system, order).source(system.name, skeleton)
