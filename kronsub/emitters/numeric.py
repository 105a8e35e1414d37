"""What generated code computes, prepared once for every language.

``Mbar qddot + hbar = fbar`` (10') becomes the first-order system
``ydot = [qdot; Mbar^-1 (fbar - hbar)]`` with state ``y = [q; qdot]``, and the
canonical form ``z = [q; p]``, ``p = Mbar qdot``,
``zdot = [Mbar^-1 p; dT/dq + fbar]`` (Lagrange's equations (A) with
``dT/dq = 1/2 qdot^T (dMbar/dq) qdot``), used by the symplectic integrator.
Common subexpressions are eliminated per function, deterministically.
"""
from __future__ import annotations

import re
from dataclasses import dataclass

import sympy

from ..core.known_system import KnownSystem
from ..core.symbols import TIME


@dataclass(frozen=True)
class Block:
    """A function body: ``temporaries`` (name, expr) then ``outputs`` (target, expr)."""

    temporaries: tuple[tuple[sympy.Symbol, sympy.Expr], ...]
    outputs: tuple[tuple[str, sympy.Expr], ...]


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
    equations: Block  # Mbar into M[] and fbar - hbar into r[], sharing subexpressions
    canonical: Block  # dT/dq + fbar into r[]
    potential: Block  # V
    positions: Block  # named points into out[]

    @property
    def n(self) -> int:
        return len(self.coordinates)

    @property
    def state(self) -> tuple[str, ...]:
        return self.coordinates + tuple(f"{q}_dot" for q in self.coordinates)


def identifier(text: str) -> str:
    """A C/Python identifier made from a model name."""
    out = re.sub(r"[^0-9A-Za-z_]+", "_", text).strip("_").lower() or "model"
    return out if not out[0].isdigit() else f"m_{out}"


def _default(value) -> str:
    """A parameter's default as a decimal literal ("" when it has none)."""
    if value is None or not sympy.sympify(value).is_number:
        return ""
    return repr(float(value))


def _block(targets: list[str], exprs: list[sympy.Expr], prefix: str) -> Block:
    symbols = sympy.numbered_symbols(prefix)
    replacements, reduced = sympy.cse(exprs, symbols=symbols, optimizations="basic", order="canonical")
    return Block(tuple(replacements), tuple(zip(targets, reduced)))


def prepare(system: KnownSystem, source: str = "") -> NumericModel:
    """Map the system's symbols to array slots and eliminate common subexpressions."""
    n = len(system.coordinates)
    params = [p for p in system.parameters]
    q_slots = {q: sympy.Symbol(f"q[{i}]") for i, q in enumerate(system.coordinates)}
    qd_slots = {v: sympy.Symbol(f"qd[{i}]") for i, v in enumerate(system.velocities)}
    p_slots = {p.symbol: sympy.Symbol(f"param[{i}]") for i, p in enumerate(params)}
    slots = {**q_slots, **qd_slots, **p_slots, TIME: sympy.Symbol("t")}

    def slot(expr) -> sympy.Expr:
        expr = sympy.sympify(expr)
        unknown = expr.free_symbols - set(slots)
        if unknown:
            from ..errors import KronsubError

            names = ", ".join(sorted(s.name for s in unknown))
            raise KronsubError(f"cannot generate code: {names} is neither a parameter, a coordinate, "
                               "a velocity nor t")
        return expr.xreplace(slots)

    M = system.mass_matrix
    r = system.forces - system.velocity_terms
    targets = [f"M[{i * n + j}]" for i in range(n) for j in range(n)]
    exprs = [slot(M[i, j]) for i in range(n) for j in range(n)]
    r_targets = [f"r[{i}]" for i in range(n)]
    equations = _block(targets + r_targets, exprs + [slot(e) for e in r], "x")
    mass = _block(targets, exprs, "x")
    velocity_terms = _block([f"h[{i}]" for i in range(n)], [slot(e) for e in system.velocity_terms], "x")
    forces = _block([f"f[{i}]" for i in range(n)], [slot(e) for e in system.forces], "x")

    qd = list(system.velocities)
    dTdq = []
    for k, qk in enumerate(system.coordinates):
        total = sympy.Integer(0)
        for i in range(n):
            for j in range(n):
                d = sympy.diff(M[i, j], qk)
                if d != 0:
                    total += d * qd[i] * qd[j] / 2
        dTdq.append(total + system.forces[k])
    canonical = _block(r_targets, [slot(e) for e in dTdq], "x")

    potential = _block(["V"], [slot(system.potential_energy)], "x")
    labels = sorted(system.points)
    pos_targets, pos_exprs, dims = [], [], []
    offset = 0
    for label in labels:
        coords = system.points[label]
        dims.append((label, len(coords)))
        for c in coords:
            pos_targets.append(f"out[{offset}]")
            pos_exprs.append(slot(c))
            offset += 1
    positions = _block(pos_targets, pos_exprs, "x")
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
        canonical=canonical,
        potential=potential,
        positions=positions,
    )
