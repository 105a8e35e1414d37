"""The trajectory as CSV: columns documented in a header, rows written as they are computed.

Lines starting with ``#`` are comments: the model, the method and tolerances,
the parameter values, and the units of the columns. Then one header row and
one row per output time: ``t``, each coordinate, each velocity, the kinetic,
potential and total energy, and (on request) the named points. The rows are
written block by block as the run produces them, and a last comment gives the
integration cost (steps, evaluations). A run that stopped early, or was
interrupted, keeps its rows and ends with a ``# incomplete: ...`` line.
"""
from __future__ import annotations

import io

import numpy as np

from ..core.known_system import KnownSystem
from ..errors import printable
from .run import Block, Run, Trajectory, _numpy_module
from .values import RunValues


class _Module:
    """The generated numpy module, made on first use."""

    def __init__(self, system: KnownSystem, outputs=None):
        self.system, self.outputs, self.namespace = system, outputs, None

    def __getitem__(self, name):
        if self.namespace is None:
            self.namespace = _numpy_module(self.system, self.outputs)
        return self.namespace[name]


def _energies(module, block: Block, param) -> tuple[np.ndarray, np.ndarray]:
    """Kinetic and potential energy per row (from the run when it computed them in C)."""
    if block.energies is not None:
        return block.energies
    T = np.array([module["kinetic_energy"](y, param) for y in block.y])
    V = np.array([module["potential_energy"](t, y, param) for t, y in zip(block.t, block.y)])
    return T, V


def energies(system: KnownSystem, traj: Trajectory, param, outputs=None) -> tuple[np.ndarray, np.ndarray]:
    """Kinetic and potential energy per row of a whole trajectory."""
    if traj.energies is not None:
        return traj.energies
    if not len(traj.y):
        return np.zeros(0), np.zeros(0)
    return _energies(_Module(system, outputs), Block(traj.t, traj.y), param)


def _point_names(module) -> list[str]:
    names = []
    for label, dim in module["POINTS"]:
        names.extend(f"{label}.{axis}" for axis in "xyz"[:dim])
    return names


def point_columns(system: KnownSystem, traj: Trajectory, param, outputs=None) -> tuple[list[str], np.ndarray]:
    module = _Module(system, outputs)
    names = _point_names(module)
    values = np.array([module["points"](y, param) for y in traj.y]).reshape(len(traj.y), len(names))
    return names, values


class CsvWriter:
    """Writes a run's CSV to ``out`` block by block; ``rows`` and ``last_t`` say how far it got."""

    def __init__(self, out, system: KnownSystem, model_path: str, values: RunValues, method: str,
                 backend: str, rtol: float, atol: float, with_points: bool = False, outputs=None):
        """``outputs`` (a scene's; None: everything) choose the columns (and the points)."""
        self.out, self.system, self.outputs = out, system, outputs
        self.with_points = with_points if outputs is None else bool(outputs.points)
        self.param = np.array(values.parameters)
        self.module = _Module(system, outputs)
        self.rows, self.last_t, self.stopped = 0, None, False
        self.want = {k: outputs is None or getattr(outputs, k) for k in ("coordinates", "velocities", "energies")}
        columns = ["t"]
        if self.want["coordinates"]:
            columns += [q.name for q in system.coordinates]
        if self.want["velocities"]:
            columns += [v.name for v in system.velocities]
        if self.want["energies"]:
            columns += ["kinetic_energy", "potential_energy", "total_energy"]
        if system.implicit is not None:  # implicit constraints: the dependent coordinates
            columns += [d.name for d in system.implicit.dependent]
        if self.with_points:
            columns += _point_names(self.module)
        # free text of the model on one comment line: a newline in the name cannot start a row
        out.write(f"# kronsub simulate: {printable(system.name)} ({printable(model_path)})\n")
        out.write(f"# method {method} ({backend} right-hand side), rtol {rtol:g}, atol {atol:g}\n")
        if system.implicit is not None:
            out.write("# dependent coordinates " + ", ".join(d.name for d in system.implicit.dependent)
                      + " from the constraints " + ", ".join(c.name for c in system.implicit.constraints)
                      + " (Newton's method on the branch of the initial configuration)\n")
        out.write("# parameters: " + ", ".join(f"{p.name}={v!r}" for p, v in zip(system.parameters,
                                                                                 values.parameters)) + "\n")
        out.write("# columns: t [s]; coordinates and velocities in the model's units (per s); energies in the "
                  "model's energy unit" + ("; points in the model's length unit" if with_points else "") + "\n")
        out.write(",".join(columns) + "\n")

    def block(self, block: Block) -> None:
        n = len(block.t)
        Y = block.y.reshape(n, -1)
        nq = Y.shape[1] // 2
        data = [block.t.reshape(-1, 1)]
        if self.want["coordinates"]:
            data.append(Y[:, :nq])
        if self.want["velocities"]:
            data.append(Y[:, nq:])
        if self.want["energies"]:
            T, V = _energies(self.module, block, self.param)
            data += [T.reshape(-1, 1), V.reshape(-1, 1), (T + V).reshape(-1, 1)]
        if self.system.implicit is not None:
            dependent = block.dependent if block.dependent is not None else \
                np.full((n, len(self.system.implicit.dependent)), np.nan)
            data.append(dependent.reshape(n, -1))
        if self.with_points:
            data.append(np.array([self.module["points"](y, self.param) for y in block.y]).reshape(n, -1))
        text = io.StringIO()
        np.savetxt(text, np.hstack(data), fmt="%.17g", delimiter=",")
        self.out.write(text.getvalue())  # whole rows only, should an interrupt come
        self.rows += n
        self.last_t = float(block.t[-1]) if n else self.last_t

    def end(self, stats: dict, complete: bool, t_fail: float | None = None, message: str = "",
            switches=()) -> None:
        for _, what in switches:  # coordinates: auto chose other independent coordinates
            self.out.write(f"# coordinates switched at {printable(what)}\n")
        cost = ", ".join(f"{v} {k}" if k != "stiff_from" else f"stiff from t = {v:.6g}" for k, v in stats.items())
        if cost:
            self.out.write(f"# cost: {cost}\n")
        if not complete:
            self.out.write(f"# incomplete: stopped at t = {t_fail!r}: {message}\n")

    def interrupted(self) -> None:
        """Mark the file incomplete after an interrupt (Ctrl-C)."""
        self.stopped = True
        self.out.write(f"# incomplete: interrupted after t = {self.last_t!r}\n")

    def stream(self, run: Run, keep=None) -> None:
        """Write the blocks of ``run`` as they are computed, then how it ended; ``keep(block)``,
        when given, sees every block too (for a plot). An interrupt (KeyboardInterrupt) marks
        the file incomplete and is raised again, so the caller keeps the file and reports it."""
        try:
            for block in run:
                self.block(block)
                if keep is not None:
                    keep(block)
        except KeyboardInterrupt:
            self.interrupted()
            raise
        self.end(run.stats, run.complete, run.t_fail, run.message, run.switches)


def write_csv(out, system: KnownSystem, model_path: str, run: Run, values: RunValues, rtol: float,
              atol: float, with_points: bool = False, keep=None, outputs=None) -> CsvWriter:
    """Stream the CSV of ``run`` to ``out`` (see :meth:`CsvWriter.stream`)."""
    writer = CsvWriter(out, system, model_path, values, run.method, run.backend, rtol, atol, with_points, outputs)
    writer.stream(run, keep)
    return writer


def to_csv(system: KnownSystem, model_path: str, traj: Trajectory, values: RunValues,
           rtol: float, atol: float, with_points: bool = False, outputs=None) -> str:
    """The CSV text of a whole trajectory."""
    block = Block(traj.t, traj.y, traj.energies, traj.dependent)
    run = Run(traj.method, traj.backend, [block] if len(traj.t) else [],
              traj.complete, traj.message, traj.t_fail, traj.stats)
    out = io.StringIO()
    write_csv(out, system, model_path, run, values, rtol, atol, with_points, outputs=outputs)
    return out.getvalue()
