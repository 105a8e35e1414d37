"""Runs from the notebook: a simulated trajectory with the CSV's columns and the metadata
``kronsub simulate`` writes, compiled numeric functions, and the animation of a run.

Every run starts from :func:`kronsub.simulation.start.starting_values`, the route of the
commands; a :class:`~.system.System` derived for a scene runs with the scene's values, span,
step, method and outputs.
"""
from __future__ import annotations

import dataclasses
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Mapping

import numpy as np

from ..core.known_system import KnownSystem
from ..errors import ModelError, Problem
from ..model.scenes import scene_system
from ..simulation.span import ANIMATION_DEFAULTS, run_span

__all__ = ["ANIMATION_DEFAULTS", "NumericSystem", "Run", "animate", "model_file", "numeric", "run_span", "scene_of",
           "settings_text", "simulate"]


@dataclass(frozen=True)
class Run:
    """A simulated trajectory: what ``kronsub simulate`` writes, as arrays.

    ``table`` holds the CSV's rows (its first column ``t``) under the CSV's header
    ``table_columns`` (coordinates, velocities, energies, ``drive_power`` for a prescribed motion,
    the dependent coordinates of a closed loop, points and reactions when asked for); ``metadata`` is what ``--meta`` writes.
    ``y = [q; qdot]`` per row with ``columns`` its names (``[q; u]`` in speeds; a first-order
    coordinate has no velocity in it), ``coordinate_count`` of them coordinates; ``notes`` the
    corrections the projection onto the constraints made to the initial values."""

    t: np.ndarray
    y: np.ndarray
    columns: tuple[str, ...]  # names of the columns of y
    kinetic_energy: np.ndarray
    potential_energy: np.ndarray
    complete: bool
    message: str
    parameters: dict[str, float]
    table_columns: tuple[str, ...] = ()
    table: np.ndarray | None = None
    metadata: dict = dataclasses.field(default_factory=dict)
    notes: tuple[str, ...] = ()
    coordinate_count: int | None = None  # None: half of y's columns

    def _split(self) -> int:
        return self.y.shape[1] // 2 if self.coordinate_count is None else self.coordinate_count

    @property
    def q(self) -> np.ndarray:
        """The coordinates' columns of ``y``."""
        return self.y[:, : self._split()]

    @property
    def qdot(self) -> np.ndarray:
        """The velocities' columns of ``y`` (the speeds ``u`` of a model in speeds)."""
        return self.y[:, self._split():]

    def _extra(self) -> dict[str, np.ndarray]:
        return {"kinetic_energy": self.kinetic_energy, "potential_energy": self.potential_energy,
                "total_energy": self.kinetic_energy + self.potential_energy}

    def __getitem__(self, name: str) -> np.ndarray:
        """A column by name: ``run["theta"]``, ``run["t"]``, ``run["total_energy"]``, any column
        of the CSV."""
        if name == "t":
            return self.t
        if name in self.columns:
            return self.y[:, self.columns.index(name)]
        if name in self.table_columns:
            return self.table[:, self.table_columns.index(name)]
        extra = self._extra()
        if name in extra:
            return extra[name]
        known = dict.fromkeys((*self.columns, *self.table_columns[1:], *extra))
        raise KeyError(f"no column '{name}'; columns: t, {', '.join(known)}")

    def to_dataframe(self):
        """A pandas DataFrame indexed by ``t``: the CSV's columns, and the energies when the
        scene left them out of it; ``frame.attrs["metadata"]`` is the run's metadata (pandas is
        optional: ImportError without it)."""
        import pandas

        data = {name: self.table[:, i] for i, name in enumerate(self.table_columns) if i} \
            if self.table is not None else {name: self.y[:, i] for i, name in enumerate(self.columns)}
        for name, values in self._extra().items():
            data.setdefault(name, values)
        frame = pandas.DataFrame(data, index=pandas.Index(self.t, name="t"))
        frame.attrs.update(metadata=self.metadata, notes=self.notes)  # what the sidecar JSON has
        return frame


def settings_text(settings: Mapping[str, object] | None) -> dict[str, str]:
    """``set=`` values as the text ``--set`` takes: numbers, or expressions as text."""
    text = {}
    for name, value in (settings or {}).items():
        if isinstance(value, bool) or not isinstance(value, (str, int, float, np.integer, np.floating)):
            raise ModelError([Problem(None, f"set {name}: expected a number or an expression as text, "
                                            f"got {value!r}")])
        if not isinstance(value, str) and not np.isfinite(value):
            raise ModelError([Problem(None, f"set {name}: {value!r} is not a finite number")])
        text[name] = value if isinstance(value, str) else repr(float(value))
    return text


def scene_of(system: KnownSystem):
    """The scene a :class:`~.system.System` was derived for (None: the whole model, or not known)."""
    return getattr(system, "scene", None)


def _trajectory(system: KnownSystem, t, dt, method, set, rtol, atol, outputs=None, jacobian: bool = False):
    """The run of ``simulate`` and ``animate``: from :func:`~.simulation.start.starting_values`."""
    from ..simulation.constrained import newton_tolerance
    from ..simulation.run import check_tolerances, explicit_only
    from ..simulation.run import simulate as run
    from ..simulation.start import starting_values

    check_tolerances(rtol, atol)
    explicit_only(system, method)
    begin = starting_values(system, settings_text(set), tolerance=newton_tolerance(rtol, atol))
    traj = run(system, begin.values, t, dt, method, rtol, atol, progress=False, outputs=outputs,
               constrained=begin.constrained, jacobian=jacobian)
    if not traj.complete:
        warnings.warn(f"the run stopped at t = {traj.t_fail:.6g}: {traj.message}; the rows so far are kept")
    return begin, traj


def simulate(system: KnownSystem, t: float | None = None, dt: float | None = None, method: str | None = None,
             set: Mapping[str, object] | None = None, rtol: float = 1e-10, atol: float = 1e-10,
             dataframe: bool | None = None, *, points: bool = False, reactions: bool = False, jacobian: bool = False):
    """Integrate from the model's initial values (a scene's over them; ``set`` overrides
    parameters and the initial state by name; a closed loop's projected onto its
    constraints) to ``t``, rows every ``dt`` (default: the scene's, else 10 and 0.01), as
    ``kronsub simulate`` does: a :class:`Run`, or its pandas DataFrame when ``dataframe`` is
    true (default: when pandas is installed). ``points`` adds the named points' positions,
    ``reactions`` the workless reactions (viewpoint (alpha)); ``jacobian``: Radau and LSODA take
    the generated exact Jacobian (``--jacobian exact``).

    >>> import kronsub
    >>> system = kronsub.load("models/hoffmann/system1.yaml").derive(scene="free")
    >>> run = system.simulate(t=0.1, dt=0.05, set={"theta": 0.2}, dataframe=False)
    >>> run.table_columns[:3], float(run["theta"][0])
    (('t', 'theta', 'phi'), 0.2)
    >>> run.metadata["scene"], run.metadata["status"]
    ('free', 'complete')
    """
    from ..simulation.power import energy_split
    from ..simulation.reactions import reaction_columns
    from ..simulation.table import energies, trajectory_table

    scene = scene_of(system)
    t, dt, method = run_span(system, t, dt, method)
    outputs = scene.outputs if scene is not None else None
    begin, traj = _trajectory(system, t, dt, method, set, rtol, atol, outputs, jacobian)
    values = begin.values
    param = np.array(values.parameters)
    extra = reaction_columns(system, traj, param, constrained=begin.constrained) if reactions else None
    model = getattr(system, "model", None)
    table_columns, table, metadata = trajectory_table(
        system, model_file(system), traj, values, rtol, atol, points, outputs, extra,
        t_end=t, dt=dt, scene=scene.name if scene is not None else None,
        source=model.source if model is not None else None, uses=model.uses if model is not None else (),
        split=energy_split(model, system))
    T, V = energies(system, traj, param)
    columns = tuple(s.name for s in system.coordinates) + tuple(system.name_of(s) for s in system.state_velocities)
    result = Run(traj.t, traj.y.reshape(len(traj.t), len(columns)), columns, T, V, traj.complete, traj.message,
                 {p.name: v for p, v in zip(system.parameters, values.parameters)}, tuple(table_columns), table,
                 metadata, begin.notes, coordinate_count=len(system.coordinates))
    if dataframe is None:
        try:
            import pandas  # noqa: F401
            dataframe = True
        except ImportError:
            dataframe = False
    return result.to_dataframe() if dataframe else result


@dataclass(frozen=True)
class NumericSystem:
    """Compiled functions of a system at fixed parameter values (the cached C library of
    :mod:`kronsub.simulation.native`; the generated numpy module without a C compiler).

    ``rhs(t, y)`` is ``[qdot; Mbar^-1 (fbar - hbar)]``; ``mass_matrix(q)``, ``forces(t, y)``,
    ``velocity_terms(y)`` (``velocity_terms(y, t)`` for a prescribed motion, whose ``hbar`` names
    ``t``), ``kinetic_energy(y)``, ``potential_energy(t, y)``. In speeds the state is ``[q; u]``,
    ``rhs`` is ``[C u + d; Mbar^-1 (fbar - hbar)]`` and the others are the equations in the speeds
    (with configuration constraints beside, ``rhs`` puts the held coordinates on them first).
    """

    rhs: Callable
    mass_matrix: Callable
    velocity_terms: Callable
    forces: Callable
    kinetic_energy: Callable
    potential_energy: Callable
    parameters: dict[str, float]
    state: tuple[str, ...]
    backend: str


def numeric(system: KnownSystem, set: Mapping[str, object] | None = None) -> NumericSystem:
    """Compiled numeric functions with the parameters' values (``set`` overrides them)."""
    import warnings

    from ..simulation.compiled import native_model
    from ..simulation.native import CompilerNotFound
    from ..simulation.fallback import numpy_module

    from ..simulation.start import starting_values

    values = starting_values(system, settings_text(set)).values
    param = np.array(values.parameters, dtype=float)
    n = len(system.coordinates)
    nv = len(system.state_velocities)
    ny, layout = n + nv, "[q; u]" if system.speeds is not None else "[q; qdot]"  # in speeds: the state [q; u]
    made: dict = {}

    def module():
        """The numpy module (mass matrix, forces, velocity terms), made when first asked for and
        within the work budget: a system projected onto its speeds at run time has its C alone."""
        if not made:
            from ..budget import scope
            from ..core.projection_work import numeric_route_advice

            with scope(), numeric_route_advice(system):
                made["module"] = numpy_module(system)
        return made["module"]

    native = None
    try:
        native = native_model(system)
    except CompilerNotFound:
        warnings.warn("no C compiler found: using the generated numpy module (slower)")

    def state(y):
        y = np.asarray(y, dtype=float).ravel()
        if y.shape != (ny,):
            raise ValueError(f"y must have {ny} entries {layout} (got {y.size})")
        return y

    def coordinates(q):
        q = np.asarray(q, dtype=float).ravel()
        if q.shape == (ny,):
            return q
        if q.shape != (n,):
            raise ValueError(f"q must have {n} entries (got {q.size})")
        return np.concatenate([q, np.zeros(nv)])

    def mass_matrix(q):
        return np.asarray(module()["mass_matrix"](coordinates(q)[:n], param), dtype=float).reshape(nv, nv)

    def forces(t, y):
        y = state(y)
        return np.asarray(module()["forces"](t, y[:n], y[n:], param), dtype=float).ravel()

    def velocity_terms(y, t=None):
        y = state(y)
        if "TIMED" not in module():  # hbar of a prescribed motion names t: velocity_terms(y, t)
            return np.asarray(module()["velocity_terms"](y[:n], y[n:], param), dtype=float).ravel()
        if t is None:
            raise ValueError("hbar of this system depends on t (a prescribed motion): call velocity_terms(y, t)")
        return np.asarray(module()["velocity_terms"](t, y[:n], y[n:], param), dtype=float).ravel()

    if native is not None:
        def rhs(t, y):
            return native.rhs(t, state(y), param)

        def kinetic(y):
            return native.kinetic_energy(state(y), param)

        def potential(t, y):
            return native.potential_energy(t, state(y), param)
    else:
        def rhs(t, y):
            return np.asarray(module()["rhs"](t, state(y), param), dtype=float)

        def kinetic(y):
            return float(module()["kinetic_energy"](state(y), param))

        def potential(t, y):
            return float(module()["potential_energy"](t, state(y), param))

    return NumericSystem(rhs, mass_matrix, velocity_terms, forces, kinetic, potential,
                         {p.name: v for p, v in zip(system.parameters, values.parameters)},
                         tuple(s.name for s in system.coordinates) + tuple(system.name_of(s) for s in system.state_velocities),
                         "C" if native is not None else "numpy")


def model_file(system: KnownSystem) -> str | None:
    """The model file a :class:`~.system.System` was derived from, as the commands name it (None: not known)."""
    model = getattr(system, "model", None)
    return Path(model.path).as_posix() if model is not None else None


def _every_point(system: KnownSystem) -> KnownSystem:
    """``system`` with every named point of its model (a scene keeps only those it asks for)."""
    model, scene = getattr(system, "model", None), scene_of(system)
    if model is None or scene is None or set(scene.outputs.points or ()) >= set(model.primitive.points()):
        return system
    return scene_system(model, scene.name, all_points=True)[1]


def animate(system: KnownSystem, output, t: float | None = None, dt: float | None = None, method: str | None = None,
            set: Mapping[str, object] | None = None, *, fps: int = 30, size: int = 480,
            progress: bool | None = False) -> int:
    """Simulate as :func:`simulate` does (default span and step: the scene's, else 5 and 0.02)
    and draw the mechanism over time into ``output``, a .gif (Pillow) or .mp4 (ffmpeg), as
    ``kronsub animate MODEL`` does (its shapes from the model's components, effects and joints,
    :mod:`kronsub.simulation.mechanism`; a system without its model: from its named points);
    a bar on stderr counts the frames with ``progress`` (None: on a terminal); the number of
    frames (needs matplotlib and Pillow)."""
    from ..simulation.animate import animate as draw
    from ..simulation.mechanism import describe, from_points, place
    from ..simulation.table import point_columns

    model = getattr(system, "model", None)
    t, dt, method = run_span(system, t, dt, method, ANIMATION_DEFAULTS)
    drawn = _every_point(system)
    begin, traj = _trajectory(drawn, t, dt, method, set, 1e-10, 1e-10)
    param = np.array(begin.values.parameters)
    if model is not None:
        shapes = place(describe(model, drawn), drawn, traj, param)
    else:
        shapes = from_points(*point_columns(drawn, traj, param))
    return draw(traj.t, shapes, Path(output), fps=fps, size=size, title=drawn.name, progress=progress)
