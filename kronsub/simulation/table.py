"""The trajectory as plain CSV, and the run's metadata as a JSON sidecar.

The CSV is one header row of column names, then one row of numbers per output
time: ``t``, each coordinate, each velocity, the kinetic, potential and total
energy (for a model with circuit parts then the magnetic, electric and mechanical energy and
the dissipated power, :mod:`kronsub.simulation.power`; for a prescribed motion the drive's
power, :mod:`.drive_power`), the dependent coordinates of implicit constraints and (on
request) the named points. Every number is written in its shortest round-trip form
(``repr(float)``: ``0.03``, not ``0.029999999999999999``), so ``float(text)`` gives back the
very double computed. No comment lines: ``csv.DictReader`` and
``pandas.read_csv`` read it without options, ``numpy.genfromtxt`` with ``names=True,
delimiter=",", deletechars=""`` (its default drops the dots of the point columns).

Everything else (the model and its hash, with those of the model files it uses as known
systems, method, tolerances, parameter values,
initial state, integration cost, complete or where it stopped) goes in the
metadata (:meth:`CsvWriter.metadata`), which the command line writes as JSON
beside the CSV (:func:`sidecar_path`). Rows are written block by block as the
run produces them; a run that stops early, or is interrupted, keeps its rows and
its metadata says so.
"""
from __future__ import annotations

import io

import numpy as np

from ..core.known_system import KnownSystem
from ..core.projection_work import projected_in_numbers
from ..core.rheonomic import depends_on_time
from ..model.file_reading import SourceFile
from ..version import __version__
from .drive_power import COLUMN as DRIVE_POWER
from .drive_power import DrivePower, driven
from .fallback import numpy_module
from .named_points import POINT_NAMES, point_namespace
from .power import COLUMNS as SPLIT_COLUMNS, EnergySplit
from .rows import Block, Trajectory
from .trajectory_file import (METADATA_FORMAT, RowWriter, format_rows, json_number, metadata_json,
                              sidecar_path)
from .values import RunValues


def model_record(name: str, file: str | None, source: SourceFile | None = None,
                 uses: tuple[SourceFile, ...] = ()) -> dict:
    """The ``model`` entry of a sidecar: its name, the file as given and the SHA-256 of the file as
    the model read it (``source``, :attr:`Model.source <kronsub.model.model.Model.source>`), with
    under ``uses`` the file and SHA-256 of each model it takes as a known system (``uses``,
    :attr:`Model.uses <kronsub.model.model.Model.uses>`: the results depend on their text too)."""
    record = {"name": name, "file": file, "sha256": source.sha256 if source is not None else None}
    if uses:
        record["uses"] = [{"file": f.file, "sha256": f.sha256} for f in uses]
    return record


class _Module:
    """The generated numpy module, made on first use; the named points of a system projected onto
    its speeds in numbers, which has none, compiled point by point (:mod:`.named_points`)."""

    def __init__(self, system: KnownSystem, outputs=None):
        self.system, self.outputs, self.namespace, self.points = system, outputs, None, None

    def __getitem__(self, name):
        if name in POINT_NAMES:
            if self.points is None:  # decided once: a row asks for every point
                self.points = point_namespace(self.system) if projected_in_numbers(self.system) else {}
            if self.points:
                return self.points[name]
        if self.namespace is None:
            self.namespace = numpy_module(self.system, self.outputs)
        return self.namespace[name]


def _points_at(module, t: float, y, param):
    """The named points at ``(t, y)``: a module of a prescribed motion (``TIMED``) takes ``t``."""
    points = module["points"]
    return points(t, y, param) if _module_is_timed(module) else points(y, param)


def _module_is_timed(module) -> bool:
    try:
        return bool(module["TIMED"])
    except KeyError:
        return False


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


def _distinct(columns: list[str], extra) -> list[str]:
    """The appended columns (the reactions), each renamed ``reaction_<name>`` (then numbered)
    where the model's own columns already use its name: a coordinate ``R_x`` beside a primitive
    ``x`` keeps its column, and the reaction ``R_x`` is ``reaction_R_x``."""
    taken, out = set(columns), []
    for name in extra:
        new, k = name, 1
        while new in taken:
            new = f"reaction_{name}" if k == 1 else f"reaction_{name}_{k}"
            k += 1
        taken.add(new)
        out.append(new)
    return out


def _point_names(module) -> list[str]:
    names = []
    for label, dim in module["POINTS"]:
        names.extend(f"{label}.{axis}" for axis in "xyz"[:dim])
    return names


def point_columns(system: KnownSystem, traj: Trajectory, param, outputs=None) -> tuple[list[str], np.ndarray]:
    module = _Module(system, outputs)
    names = _point_names(module)
    values = np.array([_points_at(module, t, y, param) for t, y in zip(traj.t, traj.y)]).reshape(len(traj.y), len(names))
    return names, values


class CsvWriter(RowWriter):
    """Writes a run's CSV to ``out`` block by block (:class:`~.trajectory_file.RowWriter`), with
    the columns and the metadata of ``system``."""

    def __init__(self, out, system: KnownSystem, model_path: str, values: RunValues, method: str,
                 backend: str, rtol: float, atol: float, with_points: bool = False, outputs=None, *,
                 t_end: float | None = None, dt: float | None = None, scene: str | None = None,
                 source: SourceFile | None = None, uses: tuple[SourceFile, ...] = (),
                 extra_columns: tuple[str, ...] = (), split: EnergySplit | None = None):
        """``outputs`` (a scene's; None: everything) choose the columns (and the points);
        ``extra_columns`` are appended (their values passed to :meth:`block`); ``source`` and
        ``uses`` are the model's files as it read them (:func:`model_record`); ``split`` (a
        model with circuit parts, :func:`~kronsub.simulation.power.energy_split`) adds the
        energies by kind and the dissipated power after the energies."""
        self.system, self.outputs = system, outputs
        self.with_points = with_points if outputs is None else bool(outputs.points)
        self.param = np.array(values.parameters)
        self.module = _Module(system, outputs)
        want = {k: outputs is None or getattr(outputs, k) for k in ("coordinates", "velocities", "energies")}
        self.split = split if want["energies"] else None
        columns = ["t"]
        if want["coordinates"]:
            columns += [q.name for q in system.coordinates]
        if want["velocities"]:
            columns += [system.name_of(v) for v in system.state_velocities]
        if want["energies"]:
            columns += ["kinetic_energy", "potential_energy", "total_energy"]
        if self.split is not None:
            columns += list(SPLIT_COLUMNS)
        self.drive = None  # the drive's power P = s^T R (x = x(xbar, t)), made on first use
        self.with_drive = want["energies"] and driven(system)
        if self.with_drive:
            columns.append(DRIVE_POWER)
        if system.implicit is not None:  # implicit constraints: the dependent coordinates
            columns += [d.name for d in system.implicit.dependent]
        if self.with_points:
            columns += _point_names(self.module)
        columns += _distinct(columns, extra_columns)
        self.columns = columns
        meta = self._start_metadata(model_path, values, method, backend, rtol, atol, t_end, dt, scene,
                                    source, uses)
        super().__init__(out, columns, meta, want)

    @property
    def plain(self) -> bool:
        """Whether the columns are only ``t``, the coordinates, the velocities and the energies:
        no circuit energies, drive power, dependent coordinates or points."""
        return self.split is None and not self.with_drive and self.system.implicit is None and not self.with_points

    def _start_metadata(self, model_path, values, method, backend, rtol, atol, t_end, dt, scene, source,
                        uses) -> dict:
        system = self.system
        state = [q.name for q in system.coordinates] + [system.name_of(v) for v in system.state_velocities]
        meta = {
            "format": METADATA_FORMAT,
            "kronsub": __version__,
            "csv": None,
            "model": model_record(system.name, model_path, source, uses),
            "scene": scene,
            "method": method,
            "right_hand_side": backend,
            "rtol": json_number(rtol),
            "atol": json_number(atol),
            "t_end": json_number(t_end),
            "dt": json_number(dt),
            "parameters": {p.name: json_number(v) for p, v in zip(system.parameters, values.parameters)},
            "initial_state": {name: json_number(v) for name, v in zip(state, values.y0)},
        }
        if system.implicit is not None:
            meta["dependent_coordinates"] = {
                "names": [d.name for d in system.implicit.dependent],
                "constraints": [c.name for c in system.implicit.constraints],
                "how": "Newton's method on the constraints, on the branch of the initial configuration",
            }
        transition = system.transition
        if transition is not None and depends_on_time(dict(transition.connection)):
            meta["prescribed_motion"] = {
                "energy_conserved": False,
                "why": "the connection names t: the drive puts power in; kinetic_energy is 1/2 qdot^T Mbar qdot, "
                       "without the drive's velocity",
            }
            if self.with_drive:
                meta["prescribed_motion"]["power"] = (
                    f"{DRIVE_POWER} is s^T R, s = dx/dt the drive's velocity and R = M xddot + h - f the reaction "
                    "on the primitive: the rate of change of the primitive's T + V with the drive's velocity in T")
        meta["columns"] = list(self.columns)
        meta["units"] = ("t in s; coordinates and velocities in the model's units (per s); energies in the "
                         "model's energy unit" + ("; dissipated_power in that unit per s" if self.split else "")
                         + ("; drive_power in energy per s" if self.with_drive else "")
                         + ("; points in the model's length unit" if self.with_points else ""))
        meta.update(status="running", complete=False, rows=0, last_t=None, cost={})
        return meta

    def energies(self, block: Block) -> tuple[np.ndarray, np.ndarray]:
        return _energies(self.module, block, self.param)

    def more(self, block: Block, Y: np.ndarray) -> list[np.ndarray]:
        """Circuit energies by kind, the drive's power, dependent coordinates, points."""
        n, data = len(block.t), []
        if self.split is not None:
            data.append(self.split.columns(block.t, Y, self.param))
        if self.with_drive:
            if self.drive is None:
                self.drive = DrivePower(self.system)
            data.append(self.drive(block.t, Y, self.param).reshape(-1, 1))
        if self.system.implicit is not None:
            dependent = block.dependent if block.dependent is not None else \
                np.full((n, len(self.system.implicit.dependent)), np.nan)
            data.append(dependent.reshape(n, -1))
        if self.with_points:
            data.append(np.array([_points_at(self.module, t, y, self.param) for t, y in zip(block.t, block.y)]).reshape(n, -1))
        return data


def trajectory_csv(system: KnownSystem, model_path: str, traj: Trajectory, values: RunValues, rtol: float,
                   atol: float, with_points: bool = False, outputs=None, extra=None, **run_info) -> tuple[str, dict]:
    """The CSV text of a whole trajectory and its metadata; ``extra`` is ``(names, values)`` of
    columns to append (the reactions)."""
    columns, data, metadata = trajectory_table(system, model_path, traj, values, rtol, atol, with_points, outputs,
                                               extra, **run_info)
    return ",".join(columns) + "\n" + (format_rows(data) if len(data) else ""), metadata


def trajectory_table(system: KnownSystem, model_path: str | None, traj: Trajectory, values: RunValues, rtol: float,
                     atol: float, with_points: bool = False, outputs=None, extra=None,
                     **run_info) -> tuple[list[str], np.ndarray, dict]:
    """The CSV's columns, its rows as numbers and the run's metadata, for a whole trajectory
    (what :func:`trajectory_csv` writes); ``extra`` as there."""
    names, data = extra if extra is not None else ((), None)
    writer = CsvWriter(io.StringIO(), system, model_path, values, traj.method, traj.backend, rtol, atol, with_points,
                       outputs, extra_columns=tuple(names), **run_info)
    rows = np.zeros((0, len(writer.columns)))
    if len(traj.t):
        block = Block(traj.t, traj.y, traj.energies, traj.dependent)
        rows = writer.data(block, data)
        writer.counted(block)
    writer.end(traj.stats, traj.complete, traj.t_fail, traj.message, traj.switches)
    return list(writer.columns), rows, writer.metadata()


__all__ = ["METADATA_FORMAT", "CsvWriter", "energies", "format_rows", "json_number", "metadata_json",
           "model_record", "point_columns", "sidecar_path", "trajectory_csv", "trajectory_table"]
