"""``coordinates: auto`` during a run: new independent coordinates where ``G_d`` goes singular.

The subspace of implicit constraints needs ``G_d = dg/dy_d`` regular (27); a choice of
independent coordinates that is regular at the initial configuration may not stay so (a
toggle position of the dependent ones). With ``coordinates: auto`` the run watches, at every
output row, how far ``G_d`` is from singular against the best choice there,

    s(d) = sigma_min(G[:, d]) / ||G||_2,

and when ``s(current) < SWITCH_RATIO s(best)`` (``best`` by the pivoted QR that picked the
first choice) it projects the same primitive onto the same constraints with the new split
(:func:`~kronsub.core.constraints.project_implicit` on the system before the constraints
that the derived system carries), maps the state (``ydot = C xbardot``), compiles the new
equations and goes on from that row. A run that stops in Newton's method or at a singular
``G_d`` first tries the same from its last row; a compiled run, which watches only the rows,
then goes over the stretch from its last row again in scipy's DOP853, whose event stops where
``G_d`` nears singular (between two rows). Rows stay in the layout of the first
choice (its independent coordinates, their velocities, its dependent coordinates), so the
CSV keeps its columns; each switch is recorded as ``(t, old, new)`` in ``Run.switches``.
"""
from __future__ import annotations

import numpy as np

from ..core.constraints import Intermediates, NumericConstraints, closed_forms, project_implicit
from ..core.known_system import KnownSystem

SWITCH_RATIO = 0.1  # switch when the current G_d is ten times closer to singular than the best one's
MAX_SWITCHES = 1000  # a run switching more often than this is chattering, not moving


def conditioning(G: np.ndarray, dependent) -> float:
    """``sigma_min(G_d) / ||G||``: 0 at a singular ``G_d``, at most 1."""
    norm = np.linalg.norm(G, 2)
    if not np.isfinite(norm) or norm == 0:
        return 0.0
    return float(np.linalg.svd(G[:, list(dependent)], compute_uv=False)[-1] / norm)


def before_constraints(system: KnownSystem) -> KnownSystem:
    """The system on ``y`` that the implicit projection started from (carried by ``implicit``)."""
    imp = system.implicit
    return KnownSystem(name=system.name, coordinates=tuple(imp.intermediate), mass_matrix=imp.metric,
                       velocity_terms=imp.velocity_terms, effect_forces=dict(imp.effect_forces),
                       potential_energy=system.potential_energy, points=dict(system.points), bodies=system.bodies,
                       dimension=system.dimension, parameters=system.parameters, description=system.description,
                       effect_potentials=dict(system.effect_potentials),
                       effect_translations=dict(system.effect_translations))


def resplit(system: KnownSystem, dependent_idx, point: dict, params: dict) -> KnownSystem:
    """The same constraints projected with the dependent coordinates ``y[dependent_idx]``; the
    branch is the configuration ``point`` (y -> value), closed forms where unique there."""
    imp = system.implicit
    y = tuple(imp.intermediate)
    dependent = tuple(y[i] for i in sorted(dependent_idx))
    independent = tuple(q for q in y if q not in dependent)
    branch = tuple((d, float(point[d])) for d in dependent)
    closed = closed_forms(imp.constraints, independent, dependent, point, params)
    return project_implicit(before_constraints(system), independent, dependent, imp.constraints,
                            closed_form=closed, branch=branch, choice="auto",
                            taken={q.name for q in y} | {s.name for s in imp.intermediates})


class Split:
    """One choice of independent coordinates during a run: its system, the intermediates'
    evaluator, and where its coordinates sit in ``y``."""

    def __init__(self, system: KnownSystem, evaluator: Intermediates):
        self.system, self.evaluator = system, evaluator
        imp = system.implicit
        y = tuple(imp.intermediate)
        self.y = y
        self.independent_idx = [y.index(q) for q in imp.independent]
        self.dependent_idx = [y.index(d) for d in imp.dependent]
        self.numeric = NumericConstraints(imp.constraints, y, evaluator.numeric_parameters)

    def full(self, row) -> tuple[np.ndarray, np.ndarray]:
        """``(y, ydot)`` of a state row ``[q; qdot]``: ``y_d`` by Newton, ``ydot = C qdot`` (27)."""
        imp = self.system.implicit
        n = len(imp.independent)
        q, qd = np.asarray(row[:n], dtype=float), np.asarray(row[n:], dtype=float)
        w = self.evaluator.at(q, qd)
        lam = np.array([w[s] for s in imp.sensitivities], dtype=float).reshape(len(imp.dependent), n)
        y = np.empty(len(self.y))
        ydot = np.empty(len(self.y))
        y[self.independent_idx], ydot[self.independent_idx] = q, qd
        y[self.dependent_idx] = [w[d] for d in imp.dependent]
        ydot[self.dependent_idx] = lam @ qd
        return y, ydot

    def row(self, y: np.ndarray, ydot: np.ndarray) -> np.ndarray:
        return np.concatenate([y[self.independent_idx], ydot[self.independent_idx]])


def watch(split: Split, y: np.ndarray) -> list[int] | None:
    """The better dependent coordinates at ``y`` when the current ones are near singular, else None."""
    G = split.numeric.jacobian(y)
    if not np.all(np.isfinite(G)):
        return None
    current = conditioning(G, split.dependent_idx)
    if current >= SWITCH_RATIO:  # the best one's is at most 1: no switch (the common, cheap case)
        return None
    best = split.numeric.pivot(y)
    if sorted(best) == sorted(split.dependent_idx):
        return None
    if current < SWITCH_RATIO * conditioning(G, best):
        return best
    return None


def describe(t: float, old: Split, new: Split) -> str:
    names = ", ".join
    return (f"t = {t:.6g}: independent coordinates {names(q.name for q in old.system.implicit.independent)} -> "
            f"{names(q.name for q in new.system.implicit.independent)} (dg/d("
            f"{names(d.name for d in old.system.implicit.dependent)}) nearly singular)")


def switched_split(old: Split, best, y: np.ndarray, tol: float) -> Split:
    """The split with dependent coordinates ``y[best]`` at the configuration ``y``."""
    params = old.evaluator.numeric_parameters
    point = {q: float(v) for q, v in zip(old.y, y)}
    system = resplit(old.system, best, point, params)
    evaluator = Intermediates(system.implicit, params, tol)
    evaluator.guess = np.array([point[d] for d in system.implicit.dependent], dtype=float)
    return Split(system, evaluator)


__all__ = ["SWITCH_RATIO", "MAX_SWITCHES", "Split", "conditioning", "describe", "resplit", "switched_split", "watch"]
