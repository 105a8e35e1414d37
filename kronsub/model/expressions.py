"""Whitelisted arithmetic expressions from model files, built as sympy objects.

Model files are data, so their text never reaches ``eval``, ``exec``,
``sympify`` or ``parse_expr``. ``ast.parse(..., mode="eval")`` only gives
us a syntax tree; this module walks it and builds sympy objects itself,
accepting numbers, declared names, ``+ - * / **``, unary signs and calls of
the functions in `FUNCTIONS`. Decimal literals become exact rationals taken
from their source text (``9.81`` is 981/100, never a binary float). Anything
else is reported as a `ModelError` located at the offending piece of text.
"""
from __future__ import annotations

import ast
import difflib
import keyword
import math
import operator
import re
import unicodedata
import warnings
from types import MappingProxyType
from typing import Mapping, NamedTuple, NoReturn

import sympy

from kronsub.budget import PER_OPERATION, WorkBudgetExceeded, charge
from kronsub.core.operations import count_ops
from kronsub.core.trigpoly import EXPANSION_HINT, expansion_problem
from kronsub.errors import Location, ModelError, Problem, near_names

MAX_LENGTH = 10_000
"""Longest expression text accepted, in characters."""
MAX_DEPTH = 100
"""Deepest nesting of operations accepted (long ``a + b + ...`` chains count once)."""
MAX_BITS = 100_000
"""Bound on the total size in bits of the exact numbers an expression may build."""
MAX_FACTORS = 100
"""Most factors accepted in one product ``a * b / c ...`` (folding is quadratic)."""
MAX_EXPONENT = 1_000
"""Largest decimal exponent accepted in a literal such as ``1e-3``."""

FUNCTIONS: Mapping[str, tuple[type[sympy.Basic], int]] = MappingProxyType({
    "sin": (sympy.sin, 1),
    "cos": (sympy.cos, 1),
    "tan": (sympy.tan, 1),
    "asin": (sympy.asin, 1),
    "acos": (sympy.acos, 1),
    "atan": (sympy.atan, 1),
    "atan2": (sympy.atan2, 2),
    "sqrt": (sympy.sqrt, 1),
    "exp": (sympy.exp, 1),
    "log": (sympy.log, 1),
    "sinh": (sympy.sinh, 1),
    "cosh": (sympy.cosh, 1),
    "tanh": (sympy.tanh, 1),
    "abs": (sympy.Abs, 1),
    "sign": (sympy.sign, 1),
})
"""The functions an expression may call: name -> (sympy function, number of arguments)."""

_DEFAULT_LOCATION = Location("<expression>", 1, 1)
_ALLOWED = ("only numbers, declared names, + - * / **, parentheses and the functions "
            + ", ".join(FUNCTIONS) + " are allowed")
_DECIMAL = re.compile(r"([+-]?)(\d*)(?:\.(\d*))?(?:[eE]([+-]?\d+))?")
_WORD = re.compile(r"[^\W\d]\w*")
_DOTTED = re.compile(r"[^\W\d]\w*(?:\s*\.\s*[^\W\d]\w*)*")  # a name, or a dotted one: upper.tip.x
_TOKEN = re.compile(r"\w+|\S")


def _literal_at(text: str, index: int) -> tuple[int, str]:
    """The whole literal (digits, letters, dots) around ``text[index]``, and where it starts."""
    start = index
    while start > 0 and (text[start - 1].isalnum() or text[start - 1] in "._"):
        start -= 1
    end = index
    while end < len(text) and (text[end].isalnum() or text[end] in "._"):
        end += 1
    return start, text[start:end] or text[index:index + 1]
_UNDEFINED = (sympy.zoo, sympy.nan, sympy.oo, -sympy.oo, sympy.I)

_BINARY_OPERATORS: dict[type, str] = {
    ast.Add: "+", ast.Sub: "-", ast.Mult: "*", ast.Div: "/", ast.Pow: "**",
    ast.BitXor: "^", ast.Mod: "%", ast.FloorDiv: "//", ast.MatMult: "@",
    ast.LShift: "<<", ast.RShift: ">>", ast.BitOr: "|", ast.BitAnd: "&",
}
_OPERATOR_HINTS = {
    ast.BitXor: "use ** for powers, e.g. x**2",
    ast.FloorDiv: "use / for division",
}
_ARITHMETIC = {ast.Mult: operator.mul, ast.Div: operator.truediv}
_UNARY_OPERATORS = {ast.UAdd: "+", ast.USub: "-", ast.Not: "not", ast.Invert: "~"}
_REJECTED = {
    ast.Lambda: "lambda expressions",
    ast.Subscript: "subscripts '[...]'",
    ast.Slice: "slices",
    ast.ListComp: "comprehensions",
    ast.SetComp: "comprehensions",
    ast.DictComp: "comprehensions",
    ast.GeneratorExp: "generator expressions",
    ast.Compare: "comparisons",
    ast.BoolOp: "'and'/'or'",
    ast.NamedExpr: "':=' assignments",
    ast.JoinedStr: "f-strings",
    ast.FormattedValue: "f-strings",
    ast.Tuple: "tuples (a ',' outside a function call)",
    ast.List: "lists",
    ast.Set: "sets",
    ast.Dict: "dictionaries",
    ast.IfExp: "'if ... else' expressions",
    ast.Starred: "starred arguments ('*x')",
    ast.Await: "'await' expressions",
    ast.Yield: "'yield' expressions",
    ast.YieldFrom: "'yield' expressions",
}

_HANDLERS = {
    ast.Constant: "_constant", ast.Name: "_name", ast.Attribute: "_attribute",
    ast.BinOp: "_binary", ast.UnaryOp: "_unary", ast.Call: "_call",
}


class _Value(NamedTuple):
    """A built sub-expression and an upper bound on the bits of its numbers."""

    expr: sympy.Expr
    bits: int


class _Reject(Exception):
    """Internal: a problem at a place inside the expression text."""

    def __init__(self, line: int, column: int, message: str, hint: str):
        super().__init__(message)
        self.line, self.column, self.message, self.hint = line, column, message, hint


def parse_expression(text: str, names: Mapping[str, sympy.Basic],
                     location: Location | None = None, *,
                     what: str = "expression", shared: dict | None = None) -> sympy.Expr:
    """Build the sympy expression written in ``text``.

    ``names`` maps every name the text may use (dotted ones like ``lower.y``
    included) to its sympy object; ``pi`` means `sympy.pi` unless ``names``
    defines it. ``location`` is where ``text`` starts in the model file and
    ``what`` names the text in messages ("expression for F", ...). Raises
    `ModelError` (and nothing else) for anything outside the whitelist.

    ``shared`` (a dict the caller keeps across the expressions of one model) remembers
    each part built: the same text with the same names met again is the same value,
    so a chain's ``l1*sin(q1)``, written in every link's position below it, is built once.
    """
    base = location or _DEFAULT_LOCATION
    if not isinstance(text, str):
        raise _error(base, what, str(text), f"expected text, got {type(text).__name__}",
                     "write the expression as text, e.g. '2*x'")
    try:
        return _Builder(text, names, shared).build_all()
    except WorkBudgetExceeded as exc:
        raise exc.at(base) from None
    except _Reject as problem:
        shift = base.shifted(problem.column - 1)
        where = shift if problem.line == 1 else Location(
            base.file, base.line + problem.line - 1, problem.column)
        raise _error(where, what, text, problem.message, problem.hint) from None
    except (RecursionError, MemoryError):
        raise _error(base, what, text, "is nested too deeply",
                     "split it into simpler parts") from None
    except Exception as exc:  # a sympy failure must still be a ModelError
        detail = str(exc).splitlines()[0][:80] if str(exc) else type(exc).__name__
        raise _error(base, what, text, f"cannot be evaluated ({detail})",
                     "simplify the expression") from None


def parse_number(text: str | int | float, location: Location | None = None, *,
                 what: str = "number") -> sympy.Rational:
    """The exact value of a plain number such as ``9.81``, ``-1.5e-3`` or ``42``.

    Decimal text gives an exact `sympy.Rational`, integers a `sympy.Integer`;
    a Python float is read from its shortest repr. Raises `ModelError`.
    """
    base = location or _DEFAULT_LOCATION
    if isinstance(text, int) and not isinstance(text, bool):
        return sympy.Integer(text)
    if isinstance(text, float):
        text = repr(text)
    hint = "write a plain number such as 9.81 or 1.5e-3"
    if not isinstance(text, str):
        raise _error(base, what, str(text), "is not a number", hint)
    stripped = text.strip()
    try:
        value = _exact_decimal(stripped) if len(stripped) <= MAX_LENGTH else None
    except ValueError:
        raise _error(base, what, text, "is too large", "use a smaller exponent") from None
    if value is None:
        raise _error(base, what, text, "is not a number", hint)
    return value


def _exact_decimal(literal: str) -> sympy.Rational | None:
    """The exact value of ``9.81``, ``.5``, ``1e-3``... (None if not a decimal).

    Raises ValueError when the number is absurdly large or precise.
    """
    match = _DECIMAL.fullmatch(literal.replace("_", ""))
    if match is None:
        return None
    sign, whole, fraction, exponent = match.groups()
    fraction = fraction or ""
    if not (whole or fraction):
        return None
    if exponent and len(exponent.lstrip("+-0")) > 4:
        raise ValueError("exponent too large")
    scale = int(exponent or 0)
    if abs(scale) > MAX_EXPONENT:
        raise ValueError("exponent too large")
    scale -= len(fraction)
    digits = int(whole + fraction)
    value = (sympy.Integer(digits * 10 ** scale) if scale >= 0
             else sympy.Rational(digits, 10 ** -scale))
    return -value if sign == "-" else value


class NumericProblem(ValueError):
    """A constant that is not a finite real double: what is wrong and a hint."""

    def __init__(self, message: str, hint: str):
        super().__init__(message)
        self.message, self.hint = message, hint


_TOO_LARGE = ("is too large for a double-precision number (more than 1.8e308)",
              "use smaller numbers or other units")
_NOT_REAL = ("is not a real number", "check the arguments of sqrt, log, asin, acos and powers of negative numbers")
_MATH_FUNCTIONS = {
    sympy.sin: math.sin, sympy.cos: math.cos, sympy.tan: math.tan, sympy.asin: math.asin,
    sympy.acos: math.acos, sympy.atan: math.atan, sympy.exp: math.exp, sympy.log: math.log,
    sympy.sinh: math.sinh, sympy.cosh: math.cosh, sympy.tanh: math.tanh, sympy.Abs: abs,
    sympy.sign: lambda x: float((x > 0) - (x < 0)), sympy.atan2: math.atan2,
}


def approximate(expr: sympy.Expr, memo: dict | None = None) -> float:
    """A double-precision value of a constant expression, every intermediate checked.

    Evaluated bottom-up in floating point, so the effort is bounded by the size
    of the expression whatever its value; raises `NumericProblem` when a part
    overflows a double, is not real, or divides by zero. (A guard: the value
    used is `constant_value`.)
    """
    memo = {} if memo is None else memo
    hit = memo.get(expr)
    if hit is not None:
        return hit
    try:
        value = _approximate(expr, memo)
    except OverflowError:
        raise NumericProblem(*_TOO_LARGE) from None
    except ZeroDivisionError:
        raise NumericProblem("divides by zero", "check the divisions") from None
    except (ValueError, TypeError) as exc:
        if isinstance(exc, NumericProblem):
            raise
        raise NumericProblem(*_NOT_REAL) from None
    if isinstance(value, complex) or math.isnan(value):
        raise NumericProblem(*_NOT_REAL)
    if math.isinf(value):
        raise NumericProblem(*_TOO_LARGE)
    memo[expr] = value
    return value


def _approximate(expr: sympy.Expr, memo: dict) -> float:
    if expr.is_Rational:
        return int(expr.p) / int(expr.q)
    if expr.is_Float or isinstance(expr, sympy.NumberSymbol):
        return float(expr)
    if expr.is_Add:
        return math.fsum(approximate(arg, memo) for arg in expr.args)
    if expr.is_Mul:
        return math.prod(approximate(arg, memo) for arg in expr.args)
    if expr.is_Pow:
        base, exponent = (approximate(arg, memo) for arg in expr.args)
        if base == 0 and exponent < 0:
            raise ZeroDivisionError
        return math.pow(base, exponent)
    function = _MATH_FUNCTIONS.get(type(expr))
    if function is not None and not expr.free_symbols:
        return float(function(*(approximate(arg, memo) for arg in expr.args)))
    if expr.has(*_UNDEFINED):
        raise NumericProblem("is undefined or not a real number (division by zero?)", _NOT_REAL[1])
    raise NumericProblem("cannot be evaluated as a number", "write a number or a formula of numbers")


def constant_value(expr: sympy.Expr, location: Location | None = None, *, what: str = "value") -> float:
    """The value of a constant expression as the nearest double, with bounded effort.

    `approximate` first checks every part is a finite real double; only then is
    the expression evaluated exactly (correctly rounded), which the check keeps
    cheap. Raises `ModelError` at ``location`` for anything else.
    """
    base = location or _DEFAULT_LOCATION
    shown = sympy.sstr(expr)
    if expr.free_symbols:
        raise _error(base, what, shown, "is not a constant",
                     "write a number or a formula of numbers and parameters with values")
    try:
        approximate(expr)
        value = complex(expr.evalf(17))
    except NumericProblem as problem:
        raise _error(base, what, shown, problem.message, problem.hint) from None
    except (TypeError, ValueError, ArithmeticError):
        raise _error(base, what, shown, _NOT_REAL[0], _NOT_REAL[1]) from None
    if value.imag or not math.isfinite(value.real):
        raise _error(base, what, shown, *_NOT_REAL)
    return value.real


def _error(where: Location, what: str, text: str, message: str, hint: str) -> ModelError:
    return ModelError([Problem(where, f"in {what} '{_shorten(text)}': {message}", hint)])


def _shorten(text: str) -> str:
    flat = " ".join(text.split())
    return flat if len(flat) <= 60 else flat[:57] + "..."


def _charge_evaluation(*args: sympy.Expr) -> None:
    """Charge the work budget for sympy's evaluation of a function or power of ``args`` as it
    is built, which walks them whole (``sin(atan2(sin(atan2(q, 1)), 1))`` doubles at each level)."""
    charge(PER_OPERATION["evaluate"] * sum(count_ops(arg) for arg in args if arg.args),
           "the expression as sympy evaluates it")


def _rational_bits(value: sympy.Rational) -> int:
    return abs(value.p).bit_length() + value.q.bit_length()


NOT_FINITE = frozenset({"nan", "inf", "infinity", "oo", "zoo"})
"""Names of values that are not finite numbers (in any case), said as such when not declared."""


def _name_hint(name: str, known: list[str]) -> str:
    """Suggest the closest known names, or how to declare a new one."""
    close = near_names(name, known)
    if close:
        return "did you mean " + " or ".join(f"'{c}'" for c in close) + "?"
    return "declare it under `parameters:` (or check the spelling)"


class _Builder:
    """Walks the syntax tree of one expression and builds sympy objects."""

    def __init__(self, text: str, names: Mapping[str, sympy.Basic], shared: dict | None = None):
        self.lead = len(text) - len(text.lstrip(" \t\f"))
        self.body = text[self.lead:]
        self.lines = re.split(r"\r\n|\r|\n", self.body)
        self.shared = shared
        self._encoded: list[bytes] | None = None
        self.names = {unicodedata.normalize("NFKC", key): value for key, value in names.items()}
        self.names.setdefault("pi", sympy.pi)
        self.known = sorted(names)
        self.name_bits: dict[str, int] = {}
        self.approximations: dict[sympy.Basic, float] = {}

    # -- locations and problems -------------------------------------------
    def _column(self, line: int, byte_offset: int) -> int:
        """1-based character column of a byte offset of a body line."""
        raw = self.lines[line - 1].encode()[:byte_offset]
        return len(raw.decode("utf-8", "replace")) + 1 + (self.lead if line == 1 else 0)

    def fail(self, node: ast.AST, message: str, hint: str,
             at: tuple[int, int] | None = None) -> NoReturn:
        """A problem at ``node`` (or at ``at`` = (line, byte offset) in the body)."""
        line, offset = at or (node.lineno, node.col_offset)
        raise _Reject(line, self._column(line, offset), message, hint)

    def fail_at(self, line: int, char_column: int, message: str, hint: str) -> NoReturn:
        """A problem at a 1-based character column of a body line."""
        raise _Reject(line, char_column + (self.lead if line == 1 else 0), message, hint)

    # -- entry point ---------------------------------------------------------
    def build_all(self) -> sympy.Expr:
        if not self.body.strip():
            raise _Reject(1, 1, "is empty", "write an expression such as 2*x")
        if len(self.body) > MAX_LENGTH:
            self.fail_at(1, 1, f"is longer than {MAX_LENGTH} characters",
                         "split it into named parts")
        tree = self._parse()
        result = self.build(tree.body, 0).expr
        if result.has(*_UNDEFINED):
            self.fail(tree.body, "is undefined or not a real number (division by zero?)",
                      "check divisions and the arguments of sqrt, log, tan...")
        return result

    def _parse(self) -> ast.Expression:
        try:
            with warnings.catch_warnings():  # Python's own SyntaxWarnings are not for users
                warnings.simplefilter("ignore")
                return ast.parse(self.body, mode="eval")
        except SyntaxError as exc:
            self._syntax_error(exc)
        except (RecursionError, MemoryError):
            self.fail_at(1, 1, "is nested too deeply", "split it into simpler parts")
        except ValueError as exc:
            self.fail_at(1, 1, f"cannot be read ({exc})", "remove unusual characters")

    def _syntax_error(self, exc: SyntaxError) -> NoReturn:
        """Report a Python syntax error in the terms of an expression."""
        self._reserved_word(exc)
        msg = exc.msg or "invalid syntax"
        line = exc.lineno or 1
        text = self.lines[line - 1] if 0 < line <= len(self.lines) else ""
        offset = exc.offset or 0
        if not exc.lineno or "null bytes" in msg:
            self.fail_at(1, 1, "contains a null character", "remove it")
        if "too many nested" in msg:
            self.fail_at(line, max(offset, 1), "is nested too deeply", "split it into simpler parts")
        if "Exceeds the limit" in msg:
            self.fail_at(line, max(offset, 1), "a number is too large", "use a smaller number")
        unclosed = re.fullmatch(r"'(.)' was never closed", msg)
        if unclosed:
            closing = {"(": ")", "[": "]", "{": "}"}.get(unclosed.group(1), "a closing bracket")
            self.fail_at(line, offset, f"expected '{closing}'",
                         f"the '{unclosed.group(1)}' here is never closed")
        if offset < 1 or offset > len(text):
            self.fail_at(line, len(text) + 1, "unexpected end of expression",
                         "the expression is incomplete: complete the last operation")
        token = _TOKEN.match(text, offset - 1) or _TOKEN.search(text, offset - 1)
        shown = token.group() if token else text[offset - 1:offset]
        if "decimal literal" in msg:
            start, literal = _literal_at(text, offset - 1)
            hint = "write products with '*', e.g. 2*x rather than 2x"
            if re.fullmatch(r"[\d.]+(e[+-]?\d+)?deg(rees?)?", literal, re.IGNORECASE):
                hint = f"angles are in radians: write {literal[:literal.lower().index('deg')]}*pi/180"
            self.fail_at(line, start + 1, f"invalid number '{literal}'", hint)
        if msg.startswith("unmatched"):
            self.fail_at(line, offset, msg, "remove it or add the matching opening bracket")
        if "string" in msg:
            self.fail_at(line, offset, "strings are not allowed", _ALLOWED)
        self.fail_at(line, offset, f"unexpected '{shown}'",
                     "check the operators and parentheses; write products with '*', e.g. 2*x")

    def _reserved_word(self, exc: SyntaxError) -> None:
        """Report a Python keyword used as a name, the usual cause of odd syntax errors."""
        for line_number, text in enumerate(self.lines, start=1):
            for word in _WORD.finditer(text):
                name = word.group()
                if keyword.iskeyword(name) and name not in ("True", "False", "None") \
                        and (name in self.names or not exc.offset):
                    self.fail_at(line_number, word.start() + 1,
                                 f"'{name}' is a reserved word and cannot be used as a name",
                                 f"rename it, e.g. '{name}_'")

    # -- the walk ------------------------------------------------------------
    def build(self, node: ast.AST, depth: int) -> _Value:
        key = self._shared_key(node, depth) if self.shared is not None else None
        if key is not None:
            hit = self.shared.get(key)
            if hit is not None:
                return hit
        value = self._build(node, depth)
        if key is not None:
            self.shared[key] = value
        return value

    def _shared_key(self, node: ast.AST, depth: int) -> tuple | None:
        """What a built part is remembered by (`parse_expression`'s ``shared``): its text, its
        depth and the value of every name in it; None for a name or a number (as quick to build
        again) or a part over several lines."""
        if type(node) not in (ast.BinOp, ast.UnaryOp, ast.Call) or node.lineno != node.end_lineno:
            return None
        if self._encoded is None:
            self._encoded = [line.encode() for line in self.lines]
        text = self._encoded[node.lineno - 1][node.col_offset:node.end_col_offset]
        names = []
        for word in _DOTTED.findall(text.decode("utf-8", "replace")):
            word = unicodedata.normalize("NFKC", "".join(word.split()))
            names.append((word, self.names.get(word)))
        key = text, depth, tuple(names)
        try:
            hash(key)
        except TypeError:  # a name whose value is not hashable: built each time
            return None
        return key

    def _build(self, node: ast.AST, depth: int) -> _Value:
        if depth > MAX_DEPTH:
            self.fail(node, f"is nested more than {MAX_DEPTH} levels deep",
                      "split it into simpler parts")
        method = _HANDLERS.get(type(node))
        if method is None:
            self._reject(node)
        charge(1, "the expression")
        value = getattr(self, method)(node, depth + 1)
        if value.bits > MAX_BITS:
            self.fail(node, "builds numbers that are too large", "use smaller numbers or exponents")
        # a constant, or the constants sympy made in combining the parts (x/exp(-800) is
        # x*exp(800)); `is_number` stops at the first symbol, where `free_symbols` walks all
        expr = value.expr
        constants = [expr] if expr.is_number else [arg for arg in expr.args if arg.is_number]
        if constants and not expr.has(*_UNDEFINED):  # those are reported by build_all
            for constant in constants:
                self._check_constant(node, constant)
        return value

    def _check_constant(self, node: ast.AST, expr: sympy.Expr) -> None:
        """A constant must be a finite real double: checked here, before anything
        evaluates it exactly (``exp(exp(20))`` has 200 million digits)."""
        try:
            approximate(expr, self.approximations)
        except NumericProblem as problem:
            segment = _shorten(ast.get_source_segment(self.body, node) or "")
            self.fail(node, f"'{segment}' {problem.message}", problem.hint)

    def _reject(self, node: ast.AST) -> NoReturn:
        what = _REJECTED.get(type(node), f"'{type(node).__name__}' constructs")
        self.fail(node, f"{what} are not allowed", _ALLOWED)

    def _constant(self, node: ast.Constant, depth: int) -> _Value:
        value = node.value
        if isinstance(value, bool) or value is None:
            if str(value) in self.names:  # declared (a parameter `None`): Python's syntax reads a constant
                self.fail(node, f"'{value}' is a reserved word and cannot be used as a name",
                          f"rename it, e.g. '{value}_'")
            self.fail(node, f"'{value}' is not allowed", "an expression must be a number: use 1 or 0")
        if isinstance(value, int):
            number = sympy.Integer(value)
            return _Value(number, _rational_bits(number))
        if isinstance(value, float):
            return self._decimal(node)
        if isinstance(value, complex):
            self.fail(node, "imaginary numbers are not allowed", "model quantities are real numbers")
        if isinstance(value, (str, bytes)):
            self.fail(node, "strings are not allowed", "remove the quotes; " + _ALLOWED)
        self.fail(node, f"'{ast.get_source_segment(self.body, node)}' is not allowed", _ALLOWED)

    def _decimal(self, node: ast.Constant) -> _Value:
        """The exact rational a decimal literal such as ``9.81`` is written as."""
        literal = ast.get_source_segment(self.body, node) or repr(node.value)
        try:
            number = _exact_decimal(literal)
        except ValueError:
            self.fail(node, f"the number '{literal}' is too large", "use a smaller exponent")
        if number is None:
            self.fail(node, f"invalid number '{literal}'", "write numbers like 9.81 or 1.5e-3")
        return _Value(number, _rational_bits(number))

    def _lookup(self, node: ast.AST, name: str) -> _Value:
        if name in self.names:
            value = self.names[name]
            if name not in self.name_bits:
                atoms = value.atoms(sympy.Rational) if isinstance(value, sympy.Basic) else ()
                self.name_bits[name] = sum(_rational_bits(atom) for atom in atoms)
            return _Value(value, self.name_bits[name])
        if name in FUNCTIONS:
            self.fail(node, f"'{name}' is a function", f"call it, e.g. {name}(x)")
        if name.lower() in NOT_FINITE:
            self.fail(node, f"'{name}' is not a finite number",
                      "a value must be a finite real number, e.g. 9.81: NaN and infinities are not values")
        self.fail(node, f"unknown name '{name}'", _name_hint(name, self.known))

    def _name(self, node: ast.Name, depth: int) -> _Value:
        return self._lookup(node, node.id)

    def _attribute(self, node: ast.Attribute, depth: int) -> _Value:
        """A dotted name such as ``upper.tip.x``; no other attribute access."""
        parts, inner, current = [], node, node
        while isinstance(current, ast.Attribute):
            parts.append(current.attr)
            inner, current = current, current.value
        if not isinstance(current, ast.Name):
            self.fail(inner, f"attribute access '.{inner.attr}' is not allowed", _ALLOWED,
                      at=(inner.end_lineno, inner.end_col_offset - len(inner.attr.encode())))
        return self._lookup(node, ".".join([current.id, *reversed(parts)]))

    def _binary(self, node: ast.BinOp, depth: int) -> _Value:
        kind = type(node.op)
        if kind in (ast.Add, ast.Sub, ast.Mult, ast.Div):
            return self._chain(node, depth)
        if kind is not ast.Pow:
            symbol = _BINARY_OPERATORS.get(kind, kind.__name__)
            self.fail(node, f"operator '{symbol}' is not allowed",
                      _OPERATOR_HINTS.get(kind, _ALLOWED), at=self._operator_position(node, symbol))
        base, exponent = self.build(node.left, depth), self.build(node.right, depth)
        estimate = base.bits + exponent.bits
        if exponent.expr.is_Rational:
            estimate += base.bits * abs(exponent.expr.p)
        if estimate > MAX_BITS:
            self.fail(node, "builds numbers that are too large", "use smaller numbers or exponents",
                      at=self._operator_position(node, "**"))
        self._check_expansion(node, base.expr, exponent.expr)
        _charge_evaluation(base.expr, exponent.expr)
        return _Value(sympy.Pow(base.expr, exponent.expr), estimate)

    def _check_expansion(self, node: ast.BinOp, base: sympy.Expr, exponent: sympy.Expr) -> None:
        """Refuse, here with its place, a power of a sum the algebra could not expand."""
        if not (exponent.is_Integer and exponent > 1 and base.free_symbols):
            return
        terms = width = 1
        for factor in sympy.Mul.make_args(base):
            if factor.is_Add:
                terms *= len(factor.args)
                width *= sum(2 if term.has(sympy.sin, sympy.cos) else 1 for term in factor.args)
        if terms == 1:
            return  # not a sum: the algebra checks what a power of it expands to
        problem = expansion_problem(terms, int(exponent), width)
        if problem is not None:
            self.fail(node, problem, EXPANSION_HINT,
                      at=self._operator_position(node, "**"))

    def _chain(self, node: ast.BinOp, depth: int) -> _Value:
        """``a + b - c`` or ``a * b / c``, with the value Python's left fold gives.

        The chain is walked without recursion, so long sums count as one level.
        Sums are built as one `sympy.Add` (the same canonical result, but linear
        time); products are folded pairwise because sympy distributes a number
        over a sum only in a two-factor product.
        """
        additive = isinstance(node.op, (ast.Add, ast.Sub))
        ops = (ast.Add, ast.Sub) if additive else (ast.Mult, ast.Div)
        steps, current = [], node
        while isinstance(current, ast.BinOp) and isinstance(current.op, ops):
            steps.append((current.op, current.right))
            current = current.left
        if not additive and len(steps) >= MAX_FACTORS:
            self.fail(node, f"has a product of more than {MAX_FACTORS} factors",
                      "split it into named parts")
        result, bits = self.build(current, depth)
        terms = [result]
        for op, operand in reversed(steps):
            value = self.build(operand, depth)
            bits += value.bits + 1
            if bits > MAX_BITS:
                self.fail(operand, "builds numbers that are too large", "use smaller numbers")
            if additive:
                terms.append(-value.expr if isinstance(op, ast.Sub) else value.expr)
            else:
                result = _ARITHMETIC[type(op)](result, value.expr)
        return _Value(sympy.Add(*terms) if additive else result, bits)

    def _operator_position(self, node: ast.BinOp, symbol: str) -> tuple[int, int]:
        """(line, byte offset) of the operator between the operands, or of the node."""
        left, right = node.left, node.right
        if left.end_lineno == right.lineno:
            raw = self.lines[right.lineno - 1].encode()
            found = raw[left.end_col_offset:right.col_offset].find(symbol.encode())
            if found >= 0:
                return right.lineno, left.end_col_offset + found
        return node.lineno, node.col_offset

    def _unary(self, node: ast.UnaryOp, depth: int) -> _Value:
        if isinstance(node.op, (ast.Not, ast.Invert)):
            symbol = _UNARY_OPERATORS[type(node.op)]
            self.fail(node, f"operator '{symbol}' is not allowed", _ALLOWED)
        operand = self.build(node.operand, depth)
        if isinstance(node.op, ast.USub):
            return _Value(-operand.expr, operand.bits + 1)
        return operand

    def _call(self, node: ast.Call, depth: int) -> _Value:
        func = node.func
        listing = "allowed functions: " + ", ".join(FUNCTIONS)
        if not isinstance(func, ast.Name):
            self.fail(func, "only the known functions can be called", listing)
        if func.id not in FUNCTIONS:
            known = func.id in self.names
            message = f"'{func.id}' is not a function" if known else f"unknown function '{func.id}'"
            close = difflib.get_close_matches(func.id, list(FUNCTIONS), n=1)
            hint = f"did you mean '{close[0]}'? " + listing if close else listing
            self.fail(func, message, hint)
        if node.keywords:
            self.fail(node.keywords[0], "keyword arguments are not allowed",
                      f"pass the arguments of {func.id}() by position")
        function, arity = FUNCTIONS[func.id]
        if len(node.args) != arity:
            plural = "s" if arity > 1 else ""
            self.fail(node, f"{func.id}() takes {arity} argument{plural}, got {len(node.args)}",
                      f"write {func.id}({', '.join('xy'[:arity])})")
        args = [self.build(arg, depth) for arg in node.args]
        _charge_evaluation(*(arg.expr for arg in args))
        return _Value(function(*(arg.expr for arg in args)), sum(arg.bits for arg in args) + 8)


__all__ = ["FUNCTIONS", "MAX_BITS", "MAX_DEPTH", "MAX_EXPONENT", "MAX_FACTORS", "MAX_LENGTH", "NOT_FINITE",
           "NumericProblem", "approximate", "constant_value", "parse_expression", "parse_number"]
