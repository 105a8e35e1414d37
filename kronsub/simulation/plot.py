"""``--plot``: a run as a picture (matplotlib, an optional extra): PNG, PDF or SVG by its name.

One panel per unit, so that no axis mixes them: angles [rad], lengths [m], angular
velocities [rad/s], velocities [m/s], and the energy change ``E - E(0)`` [J]; legends sit
outside the axes. With ``--points``, a last panel draws the named points' paths in the
plane (space seen along +y), axes equal: points that are one throughout the run (a joint)
drawn once under their joined names, a point that never moves as one marker.
A generalized coordinate is an angle when it enters the system only through the
arguments of sines and cosines (of the named points, the metric and the potential).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import sympy

from ..atomic import atomic_file
from ..core.deferred import pending
from ..core.nonholonomic_linearize import primitive_metric
from ..emitters.escape import plot_text
from .mechanism import coincident
from .table import energies, point_columns

FORMATS = {".png": "png", ".pdf": "pdf", ".svg": "svg"}
"""The names ``--plot`` writes, by their suffix, and matplotlib's format for each."""


def plot_format(path: Path) -> str | None:
    """matplotlib's format for a ``--plot`` file, from its suffix; None for one it does not write."""
    return FORMATS.get(Path(path).suffix.lower())


def angle_coordinates(system) -> set:
    """The generalized coordinates that appear in arguments of trigonometric functions."""
    exprs = [c for point in system.points.values() for c in point]
    mass = system.mass_matrix
    if pending(mass):  # not formed (a large system in speeds): the primitive's metric and C say the same
        metric = primitive_metric(system)
        mass = [*metric.weights, *metric.projection] if metric is not None else []
    exprs += list(mass) + [system.potential_energy]
    angles = set()
    for expr in exprs:
        for atom in sympy.sympify(expr).atoms(sympy.sin, sympy.cos, sympy.tan):
            angles |= atom.args[0].free_symbols & set(system.coordinates)
    return angles


def plane(position: np.ndarray) -> np.ndarray:
    """World positions (..., axes: the last index the world axis) in the drawing plane: a line
    on x, the plane as it is, space seen along +y (x to the right, z up)."""
    if position.shape[-1] == 1:
        return np.concatenate([position, np.zeros_like(position)], axis=-1)
    if position.shape[-1] == 2:
        return position
    return position[..., [0, 2]]


def _panels(system, traj, T, V) -> list[tuple[str, list[tuple[str, np.ndarray]]]]:
    n = len(system.coordinates)
    angles = angle_coordinates(system)
    charges = {q for q in system.coordinates if q.name in system.currents}  # their velocities: currents
    angle_rows = [(q.name, traj.y[:, i]) for i, q in enumerate(system.coordinates) if q in angles]
    charge_rows = [(q.name, traj.y[:, i]) for i, q in enumerate(system.coordinates) if q in charges and q not in angles]
    length_rows = [(q.name, traj.y[:, i]) for i, q in enumerate(system.coordinates)
                   if q not in angles and q not in charges]
    current_rows = []
    if system.speeds is not None:  # the state [q; u]: the speeds in a panel of their own
        turning, moving = [], [(u.name, traj.y[:, n + i]) for i, u in enumerate(system.speeds.speeds)]
    else:
        rows = [(q, system.name_of(v), traj.y[:, n + i])
                for i, (q, v) in enumerate(zip(system.coordinates, system.velocities))]
        turning = [(name, y) for q, name, y in rows if q in angles]
        current_rows = [(name, y) for q, name, y in rows if q in charges and q not in angles]
        moving = [(name, y) for q, name, y in rows if q not in angles and q not in charges]
    E = T + V
    energy_rows = [("E - E(0)", E - E[0] if len(E) else E)]
    panels = [("angles [rad]", angle_rows), ("lengths [m]", length_rows), ("charges [C]", charge_rows),
              ("angular velocities [rad/s]", turning),
              ("speeds" if system.speeds is not None else "velocities [m/s]", moving),
              ("currents [A]", current_rows), ("energy change [J]", energy_rows)]
    return [(label, rows) for label, rows in panels if rows]


def plot_trajectory(system, traj, values, path: Path, with_points: bool = False) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    param = np.array(values.parameters)
    T, V = energies(system, traj, param)
    panels = _panels(system, traj, T, V)
    names, places = point_columns(system, traj, param) if with_points and len(traj.t) else ([], None)
    paths = point_paths(names, places) if names else []
    space = any(name.endswith(".z") for name in names)
    rows = len(panels) + (1 if paths else 0)
    fig = plt.figure(figsize=(9, 2.3 * len(panels) + (4 if paths else 0)), layout="constrained")
    heights = [1] * len(panels) + ([2] if paths else [])
    grid = fig.add_gridspec(rows, 1, height_ratios=heights)
    axes = []
    for k, (label, curves) in enumerate(panels):
        ax = fig.add_subplot(grid[k], sharex=axes[0] if axes else None)
        axes.append(ax)
        for name, data in curves:
            ax.plot(traj.t, data, label=plot_text(name))
        ax.set_ylabel(label)
        ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize="small", borderaxespad=0)
        if k < len(panels) - 1:
            ax.tick_params(labelbottom=False)
    axes[-1].set_xlabel("t [s]")
    if paths:
        ax = fig.add_subplot(grid[len(panels)])
        for k, (label, xy, fixed) in enumerate(paths):
            if fixed:
                ax.plot(xy[:1, 0], xy[:1, 1], "s", color=f"C{k % 10}", ms=7, label=plot_text(f"{label} (fixed)"))
            else:
                ax.plot(xy[:, 0], xy[:, 1], color=f"C{k % 10}", marker="o", markevery=[0], ms=5,
                        label=plot_text(label))
        ax.set_aspect("equal", adjustable="datalim")
        ax.set_xlabel("x [m]")
        ax.set_ylabel("z [m]" if space else "y [m]")
        ax.set_title("paths of the named points (a dot where each starts)" + (", seen along +y" if space else ""),
                     fontsize="small")
        ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize="small", borderaxespad=0)
    fig.suptitle(f"{plot_text(system.name)}, method {plot_text(traj.method)}")
    save_figure(fig, path, plot_format(path) or "png")


def point_paths(names: list[str], values: np.ndarray) -> list[tuple[str, np.ndarray, bool]]:
    """``label.x``, ``label.y``... columns as ``(label, rows of (x, y) in the drawing plane,
    fixed)``: points that are one throughout the run (:func:`~.mechanism.coincident`) once,
    under their labels joined by `` = ``; ``fixed`` for a point that never moves."""
    groups: dict[str, list[int]] = {}
    for j, name in enumerate(names):
        label, _, axis = name.rpartition(".")
        if axis in ("x", "y", "z") and label:
            groups.setdefault(label, []).append(j)
    if not groups:
        return []
    dimension = max(len(cols) for cols in groups.values())
    labels = list(groups)
    world = np.stack([np.column_stack([values[:, c] for c in groups[label]]
                                      + [np.zeros(len(values))] * (dimension - len(groups[label])))
                      for label in labels], axis=1)
    scale = float(np.ptp(world.reshape(-1, dimension), axis=0).max(initial=0.0)) or 1.0
    out = []
    for group in coincident(labels, world, scale):
        xy = plane(world[:, group[0]])
        out.append((" = ".join(labels[j] for j in group), xy, bool(np.ptp(xy, axis=0).max(initial=0.0) == 0.0)))
    return out


def save_figure(fig, path: Path, fmt: str) -> None:
    """Save through a temporary file and a rename (the output is written atomically)."""
    import matplotlib.pyplot as plt

    try:
        with atomic_file(Path(path), binary=True) as fh:  # the user's umask, no stray temporary file
            fig.savefig(fh, dpi=100, format=fmt, bbox_inches="tight")
    finally:
        plt.close(fig)


__all__ = ["FORMATS", "angle_coordinates", "plane", "plot_format", "plot_trajectory", "point_paths", "save_figure"]
