"""``--plot``: coordinates and energy against time, as a PNG (matplotlib, an optional extra)."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ..atomic import atomic_file


def plot_trajectory(system, traj, values, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from .table import energies

    T, V = energies(system, traj, np.array(values.parameters))
    fig, (top, bottom) = plt.subplots(2, 1, sharex=True, figsize=(8, 6))
    for i, q in enumerate(system.coordinates):
        top.plot(traj.t, traj.y[:, i], label=q.name)
    top.set_ylabel("coordinates")
    top.legend(loc="upper right", fontsize="small")
    E = T + V
    bottom.plot(traj.t, E - E[0] if len(E) else E, label="E - E(0)")
    bottom.set_ylabel("energy change")
    bottom.set_xlabel("t")
    bottom.legend(loc="upper right", fontsize="small")
    fig.suptitle(f"{system.name} ({traj.method})")
    fig.tight_layout()
    try:
        with atomic_file(Path(path), binary=True) as fh:
            fig.savefig(fh, dpi=100, format="png")
    finally:
        plt.close(fig)
