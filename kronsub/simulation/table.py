"""The trajectory as CSV: columns documented in a header, written atomically.

Lines starting with ``#`` are comments: the model, the method and tolerances,
the parameter values, and the units of the columns. Then one header row and
one row per output time: ``t``, each coordinate, each velocity, the kinetic,
potential and total energy, and (on request) the named points. A run that
stopped early keeps its rows and ends with a ``# incomplete: ...`` line.
"""
from __future__ import annotations

import io

import numpy as np

from ..core.known_system import KnownSystem
from .run import Trajectory, _numpy_module
from .values import RunValues


def energies(system: KnownSystem, traj: Trajectory, param) -> tuple[np.ndarray, np.ndarray]:
    """Kinetic and potential energy per row (from the run when it computed them in C)."""
    if traj.energies is not None:
        return traj.energies
    module = _numpy_module(system)
    T = np.array([module["kinetic_energy"](y, param) for y in traj.y]) if len(traj.y) else np.zeros(0)
    V = np.array([module["potential_energy"](t, y, param) for t, y in zip(traj.t, traj.y)]) if len(traj.y) \
        else np.zeros(0)
    return T, V


def point_columns(system: KnownSystem, traj: Trajectory, param) -> tuple[list[str], np.ndarray]:
    module = _numpy_module(system)
    names = []
    for label, dim in module["POINTS"]:
        names.extend(f"{label}.{axis}" for axis in "xyz"[:dim])
    values = np.array([module["points"](y, param) for y in traj.y]).reshape(len(traj.y), len(names))
    return names, values


def to_csv(system: KnownSystem, model_path: str, traj: Trajectory, values: RunValues,
           rtol: float, atol: float, with_points: bool = False) -> str:
    """The CSV text of a run."""
    param = np.array(values.parameters)
    T, V = energies(system, traj, param)
    columns = ["t"] + [q.name for q in system.coordinates] + [v.name for v in system.velocities] + \
        ["kinetic_energy", "potential_energy", "total_energy"]
    data = [traj.t.reshape(-1, 1), traj.y, T.reshape(-1, 1), V.reshape(-1, 1), (T + V).reshape(-1, 1)]
    if with_points:
        names, pts = point_columns(system, traj, param)
        columns += names
        data.append(pts)
    table = np.hstack(data) if len(traj.t) else np.zeros((0, len(columns)))
    out = io.StringIO()
    out.write(f"# kronsub simulate: {system.name} ({model_path})\n")
    cost = ", ".join(f"{v} {k}" if k != "stiff_from" else f"stiff from t = {v:.6g}" for k, v in traj.stats.items())
    out.write(f"# method {traj.method} ({traj.backend} right-hand side), rtol {rtol:g}, atol {atol:g}"
              + (f"; {cost}" if cost else "") + "\n")
    out.write("# parameters: " + ", ".join(f"{p.name}={v!r}" for p, v in zip(system.parameters, values.parameters))
              + "\n")
    out.write("# columns: t [s]; coordinates and velocities in the model's units (per s); energies in the "
              "model's energy unit" + ("; points in the model's length unit" if with_points else "") + "\n")
    out.write(",".join(columns) + "\n")
    np.savetxt(out, table, fmt="%.17g", delimiter=",")
    if not traj.complete:
        out.write(f"# incomplete: stopped at t = {traj.t_fail!r}: {traj.message}\n")
    return out.getvalue()
