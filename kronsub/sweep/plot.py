"""``kronsub sweep --plot``: a heat map of one column over a sweep's two grid axes (matplotlib,
an optional extra), e.g. the double pendulum's flip time over its two initial angles. Axes are
labelled with the swept names and their units (a parameter's ``unit``, ``rad`` for an angle
coordinate); a cell without a value (NaN: never flipped, a run stopped) is left blank."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ..atomic import atomic_file
from ..emitters.escape import plot_text
from ..simulation.plot import angle_coordinates
from .plan import Plan

__all__ = ["heat_map", "label"]


def label(system, name: str) -> str:
    """``name [unit]`` of a swept parameter, coordinate or velocity."""
    units = {p.name: p.unit for p in system.parameters}
    angles = {q.name for q in angle_coordinates(system)}
    velocities = {system.name_of(v): q.name for q, v in zip(system.coordinates, system.velocities)}
    charges = set(system.currents)  # a charge in C, its current in A
    unit = units.get(name) or ("rad" if name in angles else "rad/s" if velocities.get(name) in angles else
                               "C" if name in charges else "A" if velocities.get(name) in charges else "")
    return f"{name} [{unit}]" if unit else name


def heat_map(folder: Path, plan: Plan, column: str, system, path: Path) -> None:
    """Write the PNG of ``column`` over ``plan``'s two grid axes, read from the dataset ``folder``."""
    import matplotlib
    import pyarrow.parquet as pq

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    first, second = plan.grids
    table = pq.read_table(folder, columns=["run", column]).to_pandas().sort_values("run")
    values = np.full(len(first) * len(second), np.nan)
    values[table["run"].to_numpy()] = table[column].to_numpy()
    grid = values.reshape(len(first), len(second))  # run = i len(second) + j
    fig, ax = plt.subplots(figsize=(6.4, 5.2))
    mesh = ax.pcolormesh(np.asarray(second.values), np.asarray(first.values), np.ma.masked_invalid(grid),
                         shading="nearest", cmap="viridis")
    fig.colorbar(mesh, ax=ax, label=plot_text(column))
    ax.set_xlabel(plot_text(label(system, second.name)))
    ax.set_ylabel(plot_text(label(system, first.name)))
    ax.set_title(plot_text(f"{system.name}: {column}"))
    try:
        with atomic_file(Path(path), binary=True) as fh:
            fig.savefig(fh, dpi=100, format="png", bbox_inches="tight")
    finally:
        plt.close(fig)
