"""Kirchhoff's laws as the connection, checked: every circuit element acts in some loop, and
every loop has inductance (the metric ``Mbar = Cᵀ L C`` (9') of the loop charges is regular)
or resistance of its own.

A loop of capacitors and sources alone has no inductance and no resistance: Kirchhoff's
voltage law fixes its charge outright, there is no motion to integrate; it is reported at the
model's coordinates, naming the loop. One with resistance but no inductance is a first-order
coordinate (:mod:`kronsub.core.first_order`) when its charge is a coordinate of its own whose
row of ``Mbar`` is zero and the resistance is positive definite on those coordinates; a loop
without inductance that shares its charge with loops that have some is reported. The check is
numeric, at random values of the coordinates, of ``t`` and of the parameters that have none.
"""
from __future__ import annotations

import numpy as np
import sympy

from ..components.electrical import Branch, CoupledInductors, Inductor
from ..core.derivative import derivative
from ..core.symbols import TIME
from ..effects.electrical import Capacitor, Gyrator, Resistor, VoltageSource
from .reader import ModelReader
from .source import excerpt

CIRCUIT_TYPES = frozenset(cls.type_name for cls in (Inductor, CoupledInductors, Branch))
ELEMENTS = (Capacitor, Resistor, VoltageSource)
RANK_TOLERANCE = 1e-9
"""Relative size below which a singular value of ``Mbar`` counts as zero (the metric of a
circuit is a sum of inductances, exact up to rounding)."""


def check_circuit(reader: ModelReader, primitive, connection: dict, coords, effects) -> None:
    """Report elements (and gyrators) the connection removes, and loops without inductance
    that are no first-order coordinates (see the module)."""
    if not any(part.type_name in CIRCUIT_TYPES for part in primitive.parts) or not coords:
        return
    if set(primitive.coordinates) - set(connection):
        return  # a primitive coordinate left unconnected is reported already
    for effect in effects:
        if isinstance(effect, Gyrator):
            for end in (effect.first, effect.second):
                image = sympy.sympify(end).xreplace(connection)
                if not image.free_symbols & set(coords):
                    reader.error(reader.locations.get(f"effect:{effect.name}"),
                                 f"gyrator '{effect.name}' couples nothing: its end {excerpt(str(end))} is "
                                 f"{excerpt(str(image))} whatever "
                                 "the generalized coordinates, under the connection",
                                 "couple a charge and a coordinate that both move (an armature's charge and "
                                 "its shaft's angle)")
                    break
        if isinstance(effect, ELEMENTS):
            image = sympy.sympify(effect.charge).xreplace(connection)
            if not image.free_symbols & set(coords):
                kind = {Capacitor: "capacitor", Resistor: "resistor", VoltageSource: "source"}[type(effect)]
                reader.error(reader.locations.get(f"effect:{effect.name}"),
                             f"{kind} '{effect.name}' acts in no loop: its charge {excerpt(str(effect.charge))} is "
                             f"{excerpt(str(image))} whatever the loop charges, under the connection",
                             "Kirchhoff's connection leaves this branch out (an open branch carries no current): "
                             "write its charge as the loop charges through it, or leave the element out")
    _loops_without_inductance(reader, primitive, connection, coords, effects)


def _loops_without_inductance(reader: ModelReader, primitive, connection, coords, effects) -> None:
    rng = np.random.default_rng(0)
    values = {s: sympy.Float(v) for s, v in reader.parameter_values().items()}
    C = sympy.Matrix([[derivative(connection[x], q) for q in coords] for x in primitive.coordinates])
    free = (C.free_symbols | primitive.metric.free_symbols) - set(values) - {TIME}
    values.update({s: sympy.Float(rng.uniform(0.5, 1.5)) for s in sorted(free, key=lambda s: s.name)})
    try:
        Cn = np.array(C.xreplace(values).evalf(), dtype=float)
        Mn = np.array(primitive.metric.xreplace(values).evalf(), dtype=float)
    except (TypeError, ValueError):
        return  # not numbers at these values: left to the derivation and the run
    Mbar = Cn.T @ Mn @ Cn
    if not np.all(np.isfinite(Mbar)):
        return
    _, sigma, vt = np.linalg.svd(Mbar)
    scale = max(float(sigma[0]) if len(sigma) else 0.0, 1e-300)
    mechanical = [a for a, x in enumerate(primitive.coordinates) if x not in _charges(primitive)]
    null = [k for k, s in enumerate(sigma) if not (s > RANK_TOLERANCE * scale and s > 0)]
    zero = [j for j in range(len(coords)) if np.all(np.abs(Mbar[j]) <= RANK_TOLERANCE * scale)]
    aligned = len(zero) == len(null)  # the null space is spanned by the coordinates whose rows are zero
    timed = {**values, TIME: sympy.Float(rng.uniform(0.5, 1.5))}  # a resistance in t, at some t
    directions = [vt[k] for k in null]
    if aligned and zero:
        try:
            D = _dissipation_matrix(effects, coords, connection, timed)[np.ix_(zero, zero)]
        except (TypeError, ValueError):
            return  # a resistance that is no number here: left to the derivation (core/first_order.py)
        level, vectors = np.linalg.eigh(D)
        unresisted = level <= RANK_TOLERANCE * max(float(np.max(np.abs(D))), 1e-300)
        if not np.any(unresisted):
            return  # first-order coordinates, each loop resisted: the mixed system (core/first_order.py)
        directions = []  # the loops among the first-order coordinates that no resistance reaches
        for vector in vectors.T[unresisted]:
            direction = np.zeros(len(coords))
            direction[zero] = vector
            directions.append(direction)
    for direction in directions:
        direction = direction / direction[np.argmax(np.abs(direction))]
        if np.any(np.abs((Cn @ direction)[mechanical]) > 1e-9):
            continue  # a motion without inertia that moves a mechanical part: left to the run's message
        loop = _combination(direction, coords)
        try:
            resisted = _dissipation_along(effects, coords, connection, direction, timed) > 0
        except (TypeError, ValueError):
            resisted = None  # a resistance that is no number here
        first = next(q for c, q in zip(direction, coords) if abs(c) > 1e-9)
        where = reader.locations.get(f"coordinate:{first.name}") or reader.locations.get("connection")
        if resisted is None:
            reader.error(where, f"the loop ({loop}) has no inductance, and kronsub cannot tell whether it has "
                                "resistance (its resistance is no number at the parameters' values)",
                         "give the loop an inductance (an `inductor` branch in it, however small) "
                         "(docs/electrical.md)")
        elif resisted and not aligned:
            reader.error(where, f"the loop ({loop}) has resistance but no inductance, and no loop charge runs "
                                "through it alone: kronsub integrates a loop without inductance as a first-order "
                                "coordinate only when it is a coordinate whose row of Mbar is zero",
                         "choose the loop charges so that this loop has a charge of its own that runs through no "
                         "inductance (or give the loop an inductance) (docs/electrical.md)")
        elif not resisted:
            reader.error(where, f"the loop ({loop}) has no inductance and no resistance: only capacitors and "
                                "sources, so Kirchhoff's voltage law fixes its charge and there is no motion",
                         "give the loop an inductance or a resistance, or leave it out of `coordinates:` "
                         "(docs/electrical.md)")


def _combination(direction, coords) -> str:
    """``0.5*q1 + q2``: the loop along ``direction``, its largest entry 1."""
    text = ""
    for c, q in zip(direction, coords):
        if abs(c) <= 1e-9:
            continue
        term = q.name if abs(abs(c) - 1) < 1e-9 else f"{abs(c):.3g}*{q.name}"
        text += ("-" if c < 0 else "") + term if not text else f" {'-' if c < 0 else '+'} {term}"
    return text


def _charges(primitive) -> set:
    """The primitive coordinates that are branch charges."""
    return {q for part in primitive.parts if part.type_name in CIRCUIT_TYPES for q in part.coordinates}


def _dissipation_matrix(effects, coords, connection, values) -> np.ndarray:
    """``D = sum R (dq/dxbar)ᵀ (dq/dxbar)``: the resistors' Rayleigh matrix in the coordinates."""
    D = np.zeros((len(coords), len(coords)))
    for effect in effects:
        if not isinstance(effect, Resistor):
            continue
        image = sympy.sympify(effect.charge).xreplace(connection)
        rate = np.array([float(derivative(image, q).xreplace(values)) for q in coords])
        D += float(sympy.sympify(effect.resistance).xreplace(values)) * np.outer(rate, rate)
    return D


def _dissipation_along(effects, coords, connection, direction, values) -> float:
    """``vᵀ D v``: the resistors' dissipation of a unit loop current along ``direction``."""
    return float(direction @ _dissipation_matrix(effects, coords, connection, values) @ direction)


__all__ = ["CIRCUIT_TYPES", "check_circuit"]
