"""Extended precision: the generated C in ``long double`` or ``_Float128``, and an integrator
exact to the type (``csrc/extended.c``: Gragg-Bulirsch-Stoer extrapolation, whose coefficients
are ratios of integers).

The model's C is :func:`kronsub.emitters.code.emit_c`'s, rewritten for the type: ``double``
becomes ``ks_real``, floating literals get the type's suffix (``L``, ``f128``) so that
``1.0/3.0`` is computed in the type, and libm functions their suffixed names (``sinl``,
``sinf128``). ``_Float128`` and its functions (``sinf128``, ``strtof128``) are glibc's (2.26
and later), in libc and libm: nothing beyond them is linked.

    digits  long: 18 (x87 80-bit)   quad: 33 (IEEE binary128, in software: ~50x slower)
"""
from __future__ import annotations

import ctypes
import math
import re
from dataclasses import dataclass

import mpmath

from ..core.known_system import KnownSystem
from ..errors import KronsubError
from .native import CSRC, compile_library

PRECISIONS = {
    # name: (C type, function suffix, literal suffix, extra prelude)
    "long": ("long double", "l", "L", ""),
    "quad": ("_Float128", "f128", "f128", "#define KS_REAL_QUAD 1\n"),
}
TEXT = 64  # characters per number, KS_EXT_TEXT of extended.c
_FUNCTIONS = ("sin", "cos", "tan", "asin", "acos", "atan", "atan2", "sinh", "cosh", "tanh", "exp", "log",
              "sqrt", "fabs", "pow", "copysign", "fmax", "fmin", "cbrt", "hypot")
_LITERAL = re.compile(r"(?<![\w.])(\d+\.\d*(?:[eE][+-]?\d+)?|\d+[eE][+-]?\d+)(?![\w.])")
_CALL = re.compile(r"\b(" + "|".join(_FUNCTIONS) + r")\s*\(")


class ExtendedError(KronsubError):
    """An extended-precision integration that could not run."""


def retype(text: str, precision: str) -> str:
    """The generated double-precision C rewritten for ``precision`` (see the module docstring)."""
    ctype, fsuffix, lsuffix, _ = PRECISIONS[precision]
    text = re.sub(r"\bdouble\b", "ks_real", text)
    text = _LITERAL.sub(lambda m: m.group(1) + lsuffix, text)
    return _CALL.sub(lambda m: m.group(1) + fsuffix + "(", text)


def prelude(precision: str) -> str:
    ctype, _, _, extra = PRECISIONS[precision]
    return ("/* kronsub extended precision: the real type of this file */\n"
            "#ifndef KS_REAL_DEFINED\n#define KS_REAL_DEFINED\n"
            "#define __STDC_WANT_IEC_60559_TYPES_EXT__ 1\n#include <math.h>\n" + extra +
            f"typedef {ctype} ks_real;\n#endif\n")


def sources(system: KnownSystem, precision: str) -> list[tuple[str, str]]:
    """``model.h``, ``model.c`` in the type, and the integrator ``extended.c``."""
    from ..emitters.code import emit_c

    if precision not in PRECISIONS:
        raise ExtendedError(f"unknown precision '{precision}'; choose one of: {', '.join(PRECISIONS)}")
    files = {g.name: g.text for g in emit_c(system, "model")}
    head = prelude(precision)
    return [("model.h", head + retype(files["model.h"], precision)),
            ("model.c", head + retype(files["model.c"], precision)),
            ("extended.c", (CSRC / "extended.c").read_text())]


def exact_text(value) -> str:
    """A number as text that the C parses without rounding: floats in hexadecimal, mpf and
    sympy numbers to 45 digits."""
    if isinstance(value, float):
        return value.hex()
    if isinstance(value, int):
        return str(value)
    import sympy

    if isinstance(value, sympy.Basic):
        return str(sympy.N(value, 45))
    with mpmath.workdps(45):
        return mpmath.nstr(mpmath.mpf(value), 45)


@dataclass(frozen=True)
class ExtendedResult:
    state: list  # mpf, the state [q; qdot] at t_end
    status: int
    steps: int
    rejected: int
    evaluations: int


class ExtendedModel:
    """A model compiled in ``precision`` with the extrapolation integrator."""

    def __init__(self, system: KnownSystem, precision: str):
        self.precision = precision
        self.ny = 2 * len(system.coordinates)
        self.nparam = len(system.parameters)
        try:
            library = compile_library(sources(system, precision), f"model_{precision}")
        except KronsubError as exc:
            raise ExtendedError(f"the {precision} precision C could not be built: {exc}\n  hint: "
                                "'quad' needs GCC and glibc 2.26 or later (_Float128)") from None
        self._lib = ctypes.CDLL(str(library))
        fn = self._lib.ks_ext_gbs
        fn.restype = ctypes.c_int
        fn.argtypes = [ctypes.POINTER(ctypes.c_char_p), ctypes.POINTER(ctypes.c_char_p), ctypes.c_char_p,
                       ctypes.c_int, ctypes.c_double, ctypes.c_long, ctypes.c_char_p,
                       ctypes.POINTER(ctypes.c_long)]
        self._gbs = fn
        self.digits = int(self._lib.ks_ext_digits())

    def integrate(self, param, y0, t_end, tol: float | None = None, stages: int | None = None,
                  max_steps: int = 1_000_000) -> ExtendedResult:
        """From ``y0`` at t = 0 to ``t_end``; numbers are passed exactly (see :func:`exact_text`).
        ``tol`` defaults to 1e-16 (long) or 1e-28 (quad), ``stages`` to 6 (long) or 10 (quad):
        more columns or a tolerance nearer the type's precision let round-off in the
        extrapolation table grow."""
        if len(param) != self.nparam or len(y0) != self.ny:
            raise ValueError(f"need {self.nparam} parameters and {self.ny} initial values")
        quad = self.digits > 25
        log10_tol = round(math.log10(tol)) if tol else (-28 if quad else -16)
        stages = stages or (10 if quad else 6)
        p = (ctypes.c_char_p * max(1, self.nparam))(*[exact_text(v).encode() for v in param])
        y = (ctypes.c_char_p * self.ny)(*[exact_text(v).encode() for v in y0])
        out = ctypes.create_string_buffer(TEXT * self.ny)
        counts = (ctypes.c_long * 3)()
        status = self._gbs(p, y, exact_text(t_end).encode(), stages, float(log10_tol), max_steps, out, counts)
        raw = out.raw
        with mpmath.workdps(45):
            state = [mpmath.mpf(raw[i * TEXT:(i + 1) * TEXT].split(b"\0")[0].decode()) for i in range(self.ny)]
        return ExtendedResult(state, int(status), counts[0], counts[1], counts[2])


__all__ = ["ExtendedError", "ExtendedModel", "ExtendedResult", "PRECISIONS", "TEXT", "exact_text", "prelude", "retype",
           "sources"]
