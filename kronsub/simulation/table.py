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


def energies(system: KnownSystem, traj: Trajectory, param, outputs=None) -> tuple[np.ndarray, np.ndarray]:
    """Kinetic and potential energy per row (from the run when it computed them in C)."""
    if traj.energies is not None:
        return traj.energies
    module = _numpy_module(system, outputs)
    T = np.array([module["kinetic_energy"](y, param) for y in traj.y]) if len(traj.y) else np.zeros(0)
    V = np.array([module["potential_energy"](t, y, param) for t, y in zip(traj.t, traj.y)]) if len(traj.y) \
        else np.zeros(0)
    return T, V


def point_columns(system: KnownSystem, traj: Trajectory, param, outputs=None) -> tuple[list[str], np.ndarray]:
    module = _numpy_module(system, outputs)
    names = []
    for label, dim in module["POINTS"]:
        names.extend(f"{label}.{axis}" for axis in "xyz"[:dim])
    values = np.array([module["points"](y, param) for y in traj.y]).reshape(len(traj.y), len(names))
    return names, values


def to_csv(system: KnownSystem, model_path: str, traj: Trajectory, values: RunValues,
           rtol: float, atol: float, with_points: bool = False, outputs=None) -> str:
    """The CSV text of a run; a scene's ``outputs`` choose the columns (and the points)."""
    param = np.array(values.parameters)
    nq = len(system.coordinates)
    Y = np.asarray(traj.y, dtype=float).reshape(len(traj.t), 2 * nq)
    columns, data = ["t"], [traj.t.reshape(-1, 1)]
    if outputs is None or outputs.coordinates:
        columns += [q.name for q in system.coordinates]
        data.append(Y[:, :nq])
    if outputs is None or outputs.velocities:
        columns += [v.name for v in system.velocities]
        data.append(Y[:, nq:])
    if outputs is None or outputs.energies:
        T, V = energies(system, traj, param, outputs)
        columns += ["kinetic_energy", "potential_energy", "total_energy"]
        data += [T.reshape(-1, 1), V.reshape(-1, 1), (T + V).reshape(-1, 1)]
    if traj.dependent is not None and system.implicit is not None:  # implicit constraints
        columns += [d.name for d in system.implicit.dependent]
        data.append(traj.dependent)
    with_points = with_points if outputs is None else bool(outputs.points)
    if with_points:
        names, pts = point_columns(system, traj, param, outputs)
        columns += names
        data.append(pts)
    table = np.hstack(data) if len(traj.t) else np.zeros((0, len(columns)))
    out = io.StringIO()
    out.write(f"# kronsub simulate: {system.name} ({model_path})\n")
    cost = ", ".join(f"{v} {k}" for k, v in traj.stats.items())
    out.write(f"# method {traj.method} ({traj.backend} right-hand side), rtol {rtol:g}, atol {atol:g}"
              + (f"; {cost}" if cost else "") + "\n")
    if system.implicit is not None:
        out.write("# dependent coordinates " + ", ".join(d.name for d in system.implicit.dependent)
                  + " from the constraints " + ", ".join(c.name for c in system.implicit.constraints)
                  + " (Newton's method on the branch of the initial configuration)\n")
    out.write("# parameters: " + ", ".join(f"{p.name}={v!r}" for p, v in zip(system.parameters, values.parameters))
              + "\n")
    out.write("# columns: t [s]; coordinates and velocities in the model's units (per s); energies in the "
              "model's energy unit" + ("; points in the model's length unit" if with_points else "") + "\n")
    out.write(",".join(columns) + "\n")
    np.savetxt(out, table, fmt="%.17g", delimiter=",")
    if not traj.complete:
        out.write(f"# incomplete: stopped at t = {traj.t_fail!r}: {traj.message}\n")
    return out.getvalue()
