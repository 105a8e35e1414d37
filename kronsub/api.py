"""The notebook face: :func:`load`, and :class:`System`, a derived system with names to
symbols, simulation, numeric functions, linearisation and Jupyter display.

:class:`~kronsub.core.known_system.KnownSystem` is pure data; :class:`System` is the same
data with these conveniences (as PyDy's ``System`` sits on ``KanesMethod``), each one of
the functions here. The simulation and the emitters are imported when first used: they
bring the code generators and their templates, which deriving alone never needs.
"""
from __future__ import annotations

import dataclasses
import re
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Mapping, Sequence

import numpy as np
import sympy

from .core.known_system import KnownSystem
from .core.linearize import Linearization
from .core.linearize import linearize as core_linearize
from .core.symbols import TIME
from .errors import KronsubError, Location, ModelError, Problem, near_names
from .model.expressions import parse_expression
from .model.loader import load_model
from .model.model import Model
from .model.scenes import derive_scene, scene_system, select_scene
from .model.requirements import parameters_in, unmet


class UnknownName(KronsubError):
    """A name that is not a coordinate, velocity or parameter of the system."""


def names(system: KnownSystem) -> dict[str, sympy.Symbol]:
    """Every name a printed equation of the system uses: coordinates, velocities,
    accelerations, parameters, ``t`` and, for a closed loop, the dependent coordinates and the
    named intermediates ``lambda_...``, ``gamma_...`` (26)-(29) with their printed closed forms."""
    out = {"t": TIME}
    groups = [system.coordinates, system.velocities, system.accelerations]
    imp = system.implicit
    if imp is not None:
        groups += [imp.intermediate, imp.intermediates, [name for name, _ in imp.definitions]]
    for group in groups:
        out.update({s.name: s for s in group})
    out.update({p.name: p.symbol for p in system.parameters})
    return out


def symbol(system: KnownSystem, name: str) -> sympy.Symbol:
    """The system's own symbol called ``name`` (they are ``real=True``: a plain
    ``sympy.Symbol(name)`` is a different symbol).

    >>> system = load("models/hoffmann/system1.yaml").derive(scene="pushed")
    >>> theta = system.symbol("theta")
    >>> theta in system.mass_matrix.free_symbols, theta.is_real
    (True, True)
    """
    known = names(system)
    if name not in known:
        near = near_names(name, sorted(known))
        hint = ("did you mean " + ", ".join(f"'{n}'" for n in near) + "?") if near else \
            "names: " + ", ".join(sorted(known))
        raise UnknownName(f"{system.name} has no symbol '{name}'; {hint}")
    return known[name]


def _value(system: KnownSystem, name: str, value, *, constant: bool, option: str | None = None) -> sympy.Expr:
    """A value given as a number or as text read by the whitelisted parser (never sympify
    of raw text); ``constant`` forbids names. ``option`` (``--at``) places problems at ``--at NAME``."""
    if isinstance(value, sympy.Basic):
        return value
    if isinstance(value, bool):
        raise ModelError([Problem(None, f"value of {name}: expected a number, got {value!r}")])
    if isinstance(value, (int, float, np.integer, np.floating)):
        return sympy.Float(float(value)) if isinstance(value, (float, np.floating)) else sympy.Integer(int(value))
    allowed = {} if constant else {p.name: p.symbol for p in system.parameters}
    where = Location(f"{option} {name}") if option else None
    return parse_expression(str(value), allowed, where, what=f"value of {name}")


def split_assignments(system: KnownSystem, at: Mapping[str, object] | None, option: str | None = None):
    """``{name: value}`` into the state/time part and the parameter part, all problems at once
    (placed at ``option NAME`` when the values came from that command-line option)."""
    point, values, problems = {}, {}, []
    params = {p.name: p.symbol for p in system.parameters}
    state = {s.name: s for s in tuple(system.coordinates) + tuple(system.velocities)}
    for name, raw in (at or {}).items():
        try:
            if name in state:
                point[state[name]] = _value(system, name, raw, constant=False, option=option)
            elif name in params:
                values[params[name]] = _value(system, name, raw, constant=True, option=option)
            elif name == "t":
                point[TIME] = _value(system, name, raw, constant=False, option=option)
            elif system.implicit is not None and name in {d.name for d in system.implicit.dependent}:
                problems.append(Problem(None, f"'{name}' is a dependent coordinate of {system.name}: the "
                                              "constraints set it", "fix the independent coordinates ("
                                        + ", ".join(q.name for q in system.coordinates) + ") instead"))
            else:
                known = sorted({*params, *state, "t"})
                near = near_names(name, known)
                problems.append(Problem(None, f"'{name}' is not a coordinate, velocity or parameter of "
                                              f"{system.name}",
                                        ("did you mean " + ", ".join(near) + "?") if near else
                                        "names: " + ", ".join(known)))
        except ModelError as exc:
            problems.extend(exc.problems)
    if problems:
        raise ModelError(problems)
    return point, values


def linearize(system: KnownSystem, at: Mapping[str, object] | None = None, inputs: Sequence[str] = (),
              *, symbolic: bool = False, initial: Mapping | None = None, option: str | None = None) -> Linearization:
    """:func:`kronsub.core.linearize.linearize` with names: ``at={"theta": "pi", "b": 0}``
    fixes coordinates, velocities, ``t`` and parameter values; ``inputs=["u"]`` names the
    parameters that are inputs. ``initial`` (default: the model's initial values carried
    by the system: the model's, a scene's over them) starts the search for an equilibrium.
    ``option`` (``"--at"``) places problems with the values at ``--at NAME``.

    >>> system = load("models/hoffmann/system1.yaml").derive(scene="free")
    >>> lin = system.linearize(at={"theta": 0, "phi": 0})
    >>> lin.equilibrium, lin.A.shape
    (True, (4, 4))
    """
    problems = []
    try:
        point, values = split_assignments(system, at, option)
    except ModelError as exc:
        problems.extend(exc.problems)
    params = {p.name: p.symbol for p in system.parameters}
    chosen = []
    for name in inputs:
        if name not in params:
            near = near_names(name, sorted(params))
            problems.append(Problem(None, f"input '{name}' is not a parameter of {system.name}",
                                    ("did you mean " + ", ".join(near) + "?") if near else
                                    "inputs are parameters: " + ", ".join(sorted(params))))
        else:
            chosen.append(params[name])
    if not problems:  # what the components need of the values (model/requirements.py)
        numbers = {p.symbol: p.value for p in system.parameters if p.value is not None}
        numbers.update(values)
        given = {s.name for s in values}
        problems.extend(unmet(system.requirements, numbers, lambda req: next(
            (Location(f"{option} {s.name}") for s in parameters_in(req) if option and s.name in given), None)))
    if problems:
        raise ModelError(problems)
    start = dict(system.initial) if initial is None else {symbol(system, k) if isinstance(k, str) else k: v
                                                           for k, v in initial.items()}
    return core_linearize(system, inputs=chosen, point=point, values=values, initial=start, symbolic=symbolic)


# ------------------------------------------------------------------------------------------
# Simulation and numeric functions
# ------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class Run:
    """A simulated trajectory: what ``kronsub simulate`` writes, as arrays.

    ``table`` holds the CSV's rows (its first column ``t``) under the CSV's header
    ``table_columns`` (coordinates, velocities, energies, the dependent coordinates of a closed
    loop, points and reactions when asked for); ``metadata`` is what ``--meta`` writes.
    ``y = [q; qdot]`` per row with ``columns`` its names; ``notes`` the corrections the
    projection onto the constraints made to the initial values."""

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

    @property
    def q(self) -> np.ndarray:
        return self.y[:, : self.y.shape[1] // 2]

    @property
    def qdot(self) -> np.ndarray:
        return self.y[:, self.y.shape[1] // 2:]

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
        scene left them out of it (pandas is optional: ImportError without it)."""
        import pandas

        data = {name: self.table[:, i] for i, name in enumerate(self.table_columns) if i} \
            if self.table is not None else {name: self.y[:, i] for i, name in enumerate(self.columns)}
        for name, values in self._extra().items():
            data.setdefault(name, values)
        return pandas.DataFrame(data, index=pandas.Index(self.t, name="t"))


def _settings(settings: Mapping[str, object] | None) -> dict[str, str]:
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
    """The scene a :class:`System` was derived for (None: the whole model, or not known)."""
    return getattr(system, "scene", None)


def run_span(system: KnownSystem, t: float | None = None, dt: float | None = None, method: str | None = None,
             defaults: tuple[float, float, str] = (10.0, 0.01, "dop853")) -> tuple[float, float, str]:
    """``(t_end, dt, method)`` of a run: each one given, else the scene's, else ``defaults``."""
    scene = scene_of(system)

    def pick(given, own, default):
        if given is not None:
            return given
        return own if own is not None else default

    return (pick(t, scene and scene.t_end, defaults[0]), pick(dt, scene and scene.dt, defaults[1]),
            pick(method, scene and scene.method, defaults[2]))


def _trajectory(system: KnownSystem, t, dt, method, set, rtol, atol, outputs=None):
    """The run of ``simulate`` and ``animate``: from :func:`~.simulation.start.starting_values`."""
    from .simulation.constrained import newton_tolerance
    from .simulation.run import check_tolerances, explicit_only
    from .simulation.run import simulate as run
    from .simulation.start import starting_values

    check_tolerances(rtol, atol)
    explicit_only(system, method)
    begin = starting_values(system, _settings(set), tolerance=newton_tolerance(rtol, atol))
    traj = run(system, begin.values, t, dt, method, rtol, atol, progress=False, outputs=outputs,
               constrained=begin.constrained)
    if not traj.complete:
        warnings.warn(f"the run stopped at t = {traj.t_fail:.6g}: {traj.message}; the rows so far are kept")
    return begin, traj


def simulate(system: KnownSystem, t: float | None = None, dt: float | None = None, method: str | None = None,
             set: Mapping[str, object] | None = None, rtol: float = 1e-10, atol: float = 1e-10,
             dataframe: bool | None = None, *, points: bool = False, reactions: bool = False):
    """Integrate from the model's initial values (a scene's over them; ``set`` overrides
    parameters and the initial state by name; a closed loop's projected onto its
    constraints) to ``t``, rows every ``dt`` (default: the scene's, else 10 and 0.01), as
    ``kronsub simulate`` does: a :class:`Run`, or its pandas DataFrame when ``dataframe`` is
    true (default: when pandas is installed). ``points`` adds the named points' positions,
    ``reactions`` the workless reactions (viewpoint (alpha)).

    >>> system = load("models/hoffmann/system1.yaml").derive(scene="free")
    >>> run = system.simulate(t=0.1, dt=0.05, set={"theta": 0.2}, dataframe=False)
    >>> run.table_columns[:3], float(run["theta"][0])
    (('t', 'theta', 'phi'), 0.2)
    >>> run.metadata["scene"], run.metadata["status"]
    ('free', 'complete')
    """
    from .simulation.fallback import numpy_module
    from .simulation.reactions import reaction_columns
    from .simulation.table import energies, trajectory_table

    scene = scene_of(system)
    t, dt, method = run_span(system, t, dt, method)
    outputs = scene.outputs if scene is not None else None
    begin, traj = _trajectory(system, t, dt, method, set, rtol, atol, outputs)
    values = begin.values
    param = np.array(values.parameters)
    extra = reaction_columns(system, traj, param, numpy_module(system), begin.constrained) if reactions else None
    model = getattr(system, "model", None)
    table_columns, table, metadata = trajectory_table(
        system, Path(model.path).as_posix() if model is not None else None, traj, values, rtol, atol, points, outputs, extra,
        t_end=t, dt=dt, scene=scene.name if scene is not None else None,
        source=model.source if model is not None else None, uses=model.uses if model is not None else ())
    T, V = energies(system, traj, param)
    columns = tuple(s.name for s in system.coordinates) + tuple(s.name for s in system.velocities)
    result = Run(traj.t, traj.y.reshape(len(traj.t), len(columns)), columns, T, V, traj.complete, traj.message,
                 {p.name: v for p, v in zip(system.parameters, values.parameters)}, tuple(table_columns), table,
                 metadata, begin.notes)
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
    ``velocity_terms(y)``, ``kinetic_energy(y)``, ``potential_energy(t, y)``.
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

    from .simulation.compiled import native_model
    from .simulation.native import CompilerNotFound
    from .simulation.fallback import numpy_module

    from .simulation.start import starting_values

    values = starting_values(system, _settings(set)).values
    param = np.array(values.parameters, dtype=float)
    n = len(system.coordinates)
    module = numpy_module(system)  # mass matrix, forces, velocity terms (numpy)
    native = None
    try:
        native = native_model(system)
    except CompilerNotFound:
        warnings.warn("no C compiler found: using the generated numpy module (slower)")

    def state(y):
        y = np.asarray(y, dtype=float).ravel()
        if y.shape != (2 * n,):
            raise ValueError(f"y must have {2 * n} entries [q; qdot] (got {y.size})")
        return y

    def coordinates(q):
        q = np.asarray(q, dtype=float).ravel()
        if q.shape == (2 * n,):
            return q
        if q.shape != (n,):
            raise ValueError(f"q must have {n} entries (got {q.size})")
        return np.concatenate([q, np.zeros(n)])

    def mass_matrix(q):
        return np.asarray(module["mass_matrix"](coordinates(q)[:n], param), dtype=float).reshape(n, n)

    def forces(t, y):
        y = state(y)
        return np.asarray(module["forces"](t, y[:n], y[n:], param), dtype=float).ravel()

    def velocity_terms(y):
        y = state(y)
        return np.asarray(module["velocity_terms"](y[:n], y[n:], param), dtype=float).ravel()

    if native is not None:
        def rhs(t, y):
            return native.rhs(t, state(y), param)

        def kinetic(y):
            return native.kinetic_energy(state(y), param)

        def potential(t, y):
            return native.potential_energy(t, state(y), param)
    else:
        def rhs(t, y):
            return np.asarray(module["rhs"](t, state(y), param), dtype=float)

        def kinetic(y):
            return float(module["kinetic_energy"](state(y), param))

        def potential(t, y):
            return float(module["potential_energy"](t, state(y), param))

    return NumericSystem(rhs, mass_matrix, velocity_terms, forces, kinetic, potential,
                         {p.name: v for p, v in zip(system.parameters, values.parameters)},
                         tuple(s.name for s in system.coordinates) + tuple(s.name for s in system.velocities),
                         "C" if native is not None else "numpy")


# ------------------------------------------------------------------------------------------
# Generated code, accuracy, animation, reactions: the commands' reach
# ------------------------------------------------------------------------------------------

C_IDENTIFIER = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")
ANIMATION_DEFAULTS = (5.0, 0.02, "dop853")  # t_end, dt, method of `animate` without a scene's


def _model_file(system: KnownSystem) -> str | None:
    model = getattr(system, "model", None)
    return Path(model.path).as_posix() if model is not None else None


def code_files(system: KnownSystem, stem: str, lang: str = "c", *, prefix: str = "ks", precision: str = "double",
               source: str | None = None) -> list[tuple[str, str]]:
    """``(file name, text)`` of the generated code (what ``kronsub codegen`` writes): C (header +
    source, in ``precision``: double, long or quad) or a numpy module (``lang="python"``), with
    the scene's outputs; ``source`` names the model file in the files' heads."""
    from .emitters.code import LANGUAGES

    if lang not in LANGUAGES:
        raise KronsubError(f"unknown language '{lang}'; choose one of {', '.join(LANGUAGES)}")
    if not C_IDENTIFIER.fullmatch(prefix):
        raise KronsubError(f"prefix {prefix!r} is not a C identifier (letters, digits and _, not starting with a digit)")
    if precision not in ("double", "long", "quad") or precision != "double" and lang != "c":
        raise KronsubError(f"precision {precision!r}: double for every language, long or quad for C")
    scene = scene_of(system)
    outputs = scene.outputs if scene is not None else None
    source = _model_file(system) or "" if source is None else source
    files = []
    for generated in LANGUAGES[lang](system, stem, source=source, prefix=prefix, outputs=outputs):
        text = generated.text
        if precision != "double":
            from .simulation.extended import prelude, retype

            text = prelude(precision) + retype(text, precision)
        files.append((generated.name, text))
    return files


def codegen(system: KnownSystem, folder=".", lang: str = "c", *, name: str | None = None, prefix: str = "ks",
            precision: str = "double") -> list[Path]:
    """Write the generated code of ``system`` into ``folder`` (created when missing), as
    ``kronsub codegen`` does; ``name`` is the stem of the files (default: the model file's).
    The paths written, in order.

    >>> import tempfile
    >>> system = load("models/hoffmann/system1.yaml").derive(scene="free")
    >>> with tempfile.TemporaryDirectory() as folder:
    ...     [p.name for p in system.codegen(folder, "python")]
    ['system1.py']
    """
    from .atomic import write_atomically

    model = getattr(system, "model", None)
    stem = name or (Path(model.path).stem if model is not None else "model")
    folder = Path(folder)
    files = code_files(system, stem, lang, prefix=prefix, precision=precision)
    folder.mkdir(parents=True, exist_ok=True)
    for file_name, text in files:
        write_atomically(folder / file_name, text)
    return [folder / file_name for file_name, _ in files]


@dataclass(frozen=True)
class Accuracy:
    """What ``kronsub accuracy`` measures: ``measurement`` (a
    :class:`~kronsub.simulation.accuracy.WorkPrecision`: the reference and one point per method
    and tolerance), with the table and metadata the command prints and writes."""

    measurement: object
    methods: tuple[str, ...]
    tolerances: tuple[float, ...]
    scene: str | None = None
    model: Model | None = None
    notes: tuple[str, ...] = ()  # corrections of the projection onto the constraints

    def markdown(self, target: float | None = None) -> str:
        """The table ``kronsub accuracy`` prints (``target``: name the cheapest point reaching it)."""
        from .simulation import accuracy_report

        return accuracy_report.markdown(self.measurement, target)

    def to_csv(self) -> str:
        """The CSV of ``--output``: one row per method and tolerance."""
        from .simulation import accuracy_report

        return accuracy_report.to_csv(self.measurement)

    def metadata(self, target: float | None = None, csv: str | None = None) -> dict:
        """The metadata of ``--meta``."""
        from .simulation import accuracy_report

        model = self.model
        return accuracy_report.metadata(self.measurement, model_file=Path(model.path).as_posix() if model else None,
                                        source=model.source if model else None, uses=model.uses if model else (),
                                        scene=self.scene, methods=self.methods, tolerances=self.tolerances,
                                        target=target, csv=csv)

    def plot(self, path, target: float | None = None) -> None:
        """The work-precision PNG of ``--plot`` (needs matplotlib)."""
        from .simulation import accuracy_report

        accuracy_report.plot(self.measurement, path, target)


def accuracy_plan(methods="all", tolerances="1e-4:1e-14", *, quick: bool = False,
                  precision: str = "double") -> tuple[tuple[str, ...], tuple[float, ...]]:
    """The methods and tolerances of an accuracy experiment, read as ``--methods``,
    ``--tolerances``, ``--quick`` and ``--precision`` are (text, or sequences)."""
    from .simulation import accuracy as acc

    chosen = acc.parse_methods(methods if isinstance(methods, str) else ",".join(methods))
    if precision != "double" and f"gbs-{precision}" not in chosen:
        chosen = chosen + (f"gbs-{precision}",)
    grid = acc.parse_tolerances(tolerances) if isinstance(tolerances, str) else tuple(float(x) for x in tolerances)
    return chosen, acc.quick_tolerances(grid) if quick else grid


def accuracy(system: KnownSystem, t: float = 10.0, methods="all", tolerances="1e-4:1e-14", *, quick: bool = False,
             digits: int | None = None, precision: str = "double", set: Mapping[str, object] | None = None) -> Accuracy:
    """The experiment of ``kronsub accuracy``: each method at each tolerance run to ``t`` from
    the model's initial values (``set`` overrides them), its error against a high-precision
    reference and its time.

    >>> system = load("models/hoffmann/system1.yaml").derive(scene="free")
    >>> result = system.accuracy(t=0.2, methods="dop853", tolerances="1e-6", quick=True)
    >>> [(p.method, p.setting) for p in result.measurement.points]
    [('dop853', 'tol 1e-06')]
    >>> print(result.markdown().splitlines()[0])
    # Work-precision: System I (scene free), t = 0 .. 0.2
    """
    from .simulation import accuracy as acc
    from .simulation.start import starting_values

    chosen, grid = accuracy_plan(methods, tolerances, quick=quick, precision=precision)
    begin = starting_values(system, _settings(set))  # Newton's tolerance 1e-14: the reference's
    default_digits = 34 if "gbs-quad" in chosen else (16 if quick else 20)
    wp = acc.measure(system, begin.values, t, chosen, grid, digits=digits or default_digits, quick=quick,
                     dependent=begin.constrained.guess if begin.constrained is not None else None)
    scene = scene_of(system)
    return Accuracy(wp, chosen, grid, scene.name if scene is not None else None, getattr(system, "model", None),
                    begin.notes)


def _every_point(system: KnownSystem) -> KnownSystem:
    """``system`` with every named point of its model (a scene keeps only those it asks for)."""
    model, scene = getattr(system, "model", None), scene_of(system)
    if model is None or scene is None or set(scene.outputs.points or ()) >= set(model.primitive.points()):
        return system
    chosen, whole = scene_system(model, scene.name, all_points=True)
    return System.of(whole, model, chosen)


def animate(system: KnownSystem, output, t: float | None = None, dt: float | None = None, method: str | None = None,
            set: Mapping[str, object] | None = None, *, fps: int = 30, size: int = 480) -> int:
    """Simulate as :func:`simulate` does (default span and step: the scene's, else 5 and 0.02)
    and draw the mechanism over time into ``output``, a .gif (pillow) or .mp4 (ffmpeg), as
    ``kronsub animate MODEL`` does; the number of frames (needs matplotlib)."""
    from .simulation.animate import animate as draw
    from .simulation.table import point_columns

    t, dt, method = run_span(system, t, dt, method, ANIMATION_DEFAULTS)
    drawn = _every_point(system)
    begin, traj = _trajectory(drawn, t, dt, method, set, 1e-10, 1e-10)
    names, values = point_columns(drawn, traj, np.array(begin.values.parameters))
    return draw(traj.t, names, values, Path(output), fps=fps, size=size, title=drawn.name)


def reactions(system: KnownSystem, fmt: str = "markdown") -> str:
    """The text of ``kronsub derive --reactions``: the equations in ``fmt`` (markdown, latex,
    json) with the workless reactions of viewpoint (alpha) as functions of the state."""
    from .emitters import EMITTERS
    from .emitters.reactions import with_reactions

    return with_reactions(EMITTERS[fmt](system), system, fmt)


# ------------------------------------------------------------------------------------------
# Display in Jupyter
# ------------------------------------------------------------------------------------------

def repr_markdown(system: KnownSystem) -> str:
    """The Markdown of ``kronsub derive`` (Jupyter's ``_repr_markdown_``)."""
    from .emitters.text import emit_markdown

    return emit_markdown(system)


def repr_latex(system: KnownSystem) -> str:
    """``Mbar qddot + hbar = fbar`` as one display-math block (Jupyter's ``_repr_latex_``).

    Only symbols reach it (never the model's free text)."""
    from .emitters.report import latex_printer

    show = latex_printer(system.coordinates)
    rows = " \\\\ ".join(f"{show(eq.lhs)} &= {show(eq.rhs)}" for eq in system.equations())
    return "$$\\begin{aligned} " + rows + " \\end{aligned}$$"


# ------------------------------------------------------------------------------------------
# The notebook's objects
# ------------------------------------------------------------------------------------------

class System(KnownSystem):
    """A derived system as a notebook sees it: the :class:`KnownSystem`'s data (``mass_matrix``
    is ``Mbar = Cᵀ M C`` (9'), ``velocity_terms``, ``forces``, ``coordinates``, energies...),
    with :meth:`symbol`, :meth:`simulate`, :meth:`numeric`, :meth:`linearize` and its Jupyter
    display. The conveniences add no data: a ``System`` goes wherever a ``KnownSystem`` does."""

    @classmethod
    def of(cls, known: KnownSystem, model: Model | None = None, scene=None) -> System:
        """``known``'s data, with the notebook's conveniences; ``model`` and ``scene`` say what
        it was derived from (its runs take the scene's span, step, method and outputs, and
        their metadata names the model file)."""
        if isinstance(known, cls) and model is None and scene is None:
            return known
        system = cls(**{f.name: getattr(known, f.name) for f in dataclasses.fields(KnownSystem)})
        object.__setattr__(system, "_origin", (model, scene))
        return system

    @property
    def model(self) -> Model | None:
        """The model this system was derived from (None when not known)."""
        return getattr(self, "_origin", (None, None))[0]

    @property
    def scene(self):
        """The :class:`~kronsub.model.scenes.Scene` this system was derived for (None: the
        whole model)."""
        return getattr(self, "_origin", (None, None))[1]

    def symbol(self, name: str) -> sympy.Symbol:
        """The system's symbol called ``name`` (kronsub's symbols are ``real=True``)."""
        return symbol(self, name)

    def simulate(self, t: float | None = None, dt: float | None = None, method: str | None = None, set=None,
                 **options):
        """Simulate from the model's initial values; see :func:`simulate`."""
        return simulate(self, t, dt, method, set, **options)

    def codegen(self, folder=".", lang: str = "c", **options) -> list[Path]:
        """Write C (header + source) or a numpy module into ``folder``; see :func:`codegen`."""
        return codegen(self, folder, lang, **options)

    def accuracy(self, t: float = 10.0, methods="all", tolerances="1e-4:1e-14", **options) -> Accuracy:
        """Error against a high-precision reference, per method and tolerance; see :func:`accuracy`."""
        return accuracy(self, t, methods, tolerances, **options)

    def animate(self, output, t: float | None = None, dt: float | None = None, method: str | None = None,
                set=None, **options) -> int:
        """Write a GIF or MP4 of a run; see :func:`animate`."""
        return animate(self, output, t, dt, method, set, **options)

    def reactions(self, fmt: str = "markdown") -> str:
        """The derived equations with the workless reactions (viewpoint (alpha)); see :func:`reactions`."""
        return reactions(self, fmt)

    def numeric(self, set=None) -> NumericSystem:
        """Compiled ``rhs``, ``mass_matrix``, energies...; see :func:`numeric`."""
        return numeric(self, set)

    def linearize(self, at=None, inputs=(), *, symbolic: bool = False) -> Linearization:
        """``A``, ``B`` about an operating point; see :func:`linearize`."""
        return linearize(self, at, inputs, symbolic=symbolic)

    def _repr_markdown_(self) -> str:
        return repr_markdown(self)

    def _repr_latex_(self) -> str:
        return repr_latex(self)


class LoadedModel(Model):
    """A model as :func:`load` gives it: a :class:`~kronsub.model.model.Model` whose
    :meth:`derive` returns a :class:`System`."""

    def derive(self, *, scene: str | None = None, cache: bool = True) -> System:
        """The equations of motion by projection onto the subspace (9'), (E), (F), of the
        ``scene`` called so (default: the model's only scene if it has exactly one, else every
        effect; the rule of ``--scene``). An unknown scene is a ``ModelError`` naming the valid ones.

        >>> system = load("models/hoffmann/system1.yaml").derive(scene="free")
        >>> system.name, [q.name for q in system.coordinates]
        ('System I (scene free)', ['theta', 'phi'])
        >>> sorted(system.effect_forces)
        ['gravity']
        """
        chosen = select_scene(self, scene)
        system = super().derive(cache=cache) if chosen is None else derive_scene(self, chosen, cache=cache)
        return System.of(system, self, chosen)


def load(path, *, text: str | None = None, cache: bool = True) -> LoadedModel:
    """Load and validate a model file (see :func:`kronsub.load`)."""
    model = load_model(path, text=text, cache=cache)
    return LoadedModel(**{f.name: getattr(model, f.name) for f in dataclasses.fields(Model)})


__all__ = ["ANIMATION_DEFAULTS", "Accuracy", "C_IDENTIFIER", "LoadedModel", "NumericSystem", "Run", "System",
           "UnknownName", "accuracy", "accuracy_plan", "animate", "code_files", "codegen", "linearize", "load", "names",
           "numeric", "reactions", "repr_latex", "repr_markdown", "run_span", "scene_of", "simulate",
           "split_assignments", "symbol"]
