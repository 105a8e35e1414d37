"""``--plot``: coordinates and energy against time, as a PNG (matplotlib, an optional extra)."""
from __future__ import annotations

import os
import tempfile
from pathlib import Path

import numpy as np


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
    fd, tmp = tempfile.mkstemp(dir=Path(path).resolve().parent, suffix=".png")
    os.close(fd)
    try:
        fig.savefig(tmp, dpi=100, format="png")
        os.replace(tmp, path)
    finally:
        plt.close(fig)
        if os.path.exists(tmp):
            os.unlink(tmp)
