"""The equations (10') as a tape of elementary operations: nodes in topological order whose
Taylor coefficients follow by the recurrences of automatic differentiation, read by the
high-precision reference (:mod:`kronsub.simulation.reference`) and written out as C by
:mod:`.taylor_c`."""
from __future__ import annotations

import mpmath
import sympy

from ..core.symbols import TIME
from ..errors import KronsubError

__all__ = ["Tape", "Unsupported"]


class Unsupported(KronsubError):
    """An expression the Taylor route has no recurrence for."""


class Tape:
    """Nodes in topological order: ``(kind, args, data)``; inputs first."""

    def __init__(self, state: list[sympy.Symbol], constants: dict, parameters: tuple = ()):
        self.nodes: list[tuple[str, tuple, object]] = []
        self.memo: dict = {}
        self.constants = constants  # parameter symbol -> mpf
        for i, s in enumerate(state):
            self.memo[s] = self._add("state", (), i)
        self.memo[TIME] = self._add("time", (), None)
        for i, s in enumerate(parameters):  # parameters known only at run time (generated C)
            self.memo[s] = self._add("param", (), i)

    def _add(self, kind, args, data=None) -> int:
        self.nodes.append((kind, tuple(args), data))
        return len(self.nodes) - 1

    def const(self, value) -> int:
        return self._add("const", (), mpmath.mpf(value))

    def solve(self, A: list[list[int]], B: list[list[int]], what: str) -> list[list[int]]:
        """Nodes of ``X`` with ``A X = B`` (``A`` m x m, ``B`` m x c nodes), solved order by
        order: ``A_0 X_k = B_k - sum_{j>=1} A_j X_{k-j}``; ``what`` names ``A`` in errors."""
        m, c = len(A), len(B[0]) if B else 0
        block = self._add("solve", [a for row in A for a in row] + [b for row in B for b in row], (m, c, what))
        return [[self._add("pick", (block,), r * c + j) for j in range(c)] for r in range(m)]

    def is_const(self, node: int) -> bool:
        return self.nodes[node][0] == "const"

    def value(self, node: int):
        return self.nodes[node][2]

    def node(self, expr) -> int:
        """The node computing ``expr`` (shared when the same subexpression recurs)."""
        if expr in self.memo:
            return self.memo[expr]
        result = self._build(expr)
        self.memo[expr] = result
        return result

    def _build(self, e) -> int:
        if e.is_Symbol:
            if e in self.constants:
                return self._add("const", (), self.constants[e])
            raise Unsupported(f"unknown symbol {e} in the equations")
        if e.is_Number or e.is_NumberSymbol:
            return self.const(mpmath.mpf(sympy.N(e, mpmath.mp.dps + 5)) if not e.is_Rational
                              else mpmath.mpf(int(e.p)) / int(e.q))
        if e.is_Add:
            args = [self.node(a) for a in e.args]
            if all(self.is_const(a) for a in args):
                return self.const(mpmath.fsum(self.value(a) for a in args))
            return self._add("add", args)
        if e.is_Mul:
            scale, factors = mpmath.mpf(1), []
            for a in e.args:
                n = self.node(a)
                if self.is_const(n):
                    scale *= self.value(n)
                else:
                    factors.append(n)
            if not factors:
                return self.const(scale)
            node = factors[0]
            for f in factors[1:]:
                node = self._add("mul", (node, f))
            return node if scale == 1 else self._add("scale", (node,), scale)
        if e.is_Pow:
            base, power = self.node(e.base), self.node(e.exp)
            if not self.is_const(power):  # b^p = exp(p log b)
                return self._add("exp", (self._add("mul", (power, self._add("log", (base,)))),))
            p = self.value(power)
            if self.is_const(base):
                return self.const(self.value(base) ** p)
            if p == 1:
                return base
            if p == 2:
                return self._add("mul", (base, base))
            return self._add("pow", (base,), p)
        if isinstance(e, (sympy.sin, sympy.cos)):
            arg = self.node(e.args[0])
            if self.is_const(arg):
                return self.const((mpmath.sin if isinstance(e, sympy.sin) else mpmath.cos)(self.value(arg)))
            pair = self.memo.get(("sincos", arg))
            if pair is None:
                pair = self.memo[("sincos", arg)] = self._add("sincos", (arg,))
            return self._add("sin" if isinstance(e, sympy.sin) else "cos", (pair,))
        if isinstance(e, sympy.exp):
            arg = self.node(e.args[0])
            return self.const(mpmath.exp(self.value(arg))) if self.is_const(arg) else self._add("exp", (arg,))
        if isinstance(e, sympy.log) and len(e.args) == 1:
            arg = self.node(e.args[0])
            return self.const(mpmath.log(self.value(arg))) if self.is_const(arg) else self._add("log", (arg,))
        rewrites = {sympy.tan: lambda x: sympy.sin(x) / sympy.cos(x),
                    sympy.sinh: lambda x: (sympy.exp(x) - sympy.exp(-x)) / 2,
                    sympy.cosh: lambda x: (sympy.exp(x) + sympy.exp(-x)) / 2,
                    sympy.tanh: lambda x: (sympy.exp(2 * x) - 1) / (sympy.exp(2 * x) + 1)}
        for fn, rewrite in rewrites.items():
            if isinstance(e, fn):
                return self.node(rewrite(e.args[0]))
        derivatives = {sympy.atan: lambda x: 1 / (1 + x ** 2),  # v' = g(a) a'
                       sympy.asin: lambda x: (1 - x ** 2) ** sympy.Rational(-1, 2),
                       sympy.acos: lambda x: -(1 - x ** 2) ** sympy.Rational(-1, 2)}
        for fn, derivative in derivatives.items():
            if isinstance(e, fn):
                arg = self.node(e.args[0])
                if self.is_const(arg):
                    return self.const(getattr(mpmath, fn.__name__)(self.value(arg)))
                return self._add("integral", (arg, self.node(derivative(e.args[0]))),
                                 fn.__name__)
        if isinstance(e, (sympy.Abs, sympy.sign)):
            arg = self.node(e.args[0])
            kind = "abs" if isinstance(e, sympy.Abs) else "sign"
            if self.is_const(arg):
                v = self.value(arg)
                return self.const(abs(v) if kind == "abs" else mpmath.sign(v))
            return self._add(kind, (arg,))
        raise Unsupported(f"the high-precision reference has no Taylor rule for {type(e).__name__}\n"
                          "  hint: rules exist for + * / **, sin cos tan asin acos atan sinh cosh tanh exp log "
                          "sqrt abs sign")
