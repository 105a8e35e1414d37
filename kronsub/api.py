"""The notebook face: :func:`load`, and :class:`System`, a derived system with names to
symbols, simulation, numeric functions, linearisation and Jupyter display.

:class:`~kronsub.core.known_system.KnownSystem` is pure data; :class:`System` is the same
data with these conveniences (as PyDy's ``System`` sits on ``KanesMethod``), each one of
the functions here. The simulation and the emitters are imported when first used: they
bring the code generators and their templates, which deriving alone never needs.
"""
from __future__ import annotations

import dataclasses
import warnings
from dataclasses import dataclass
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
from .model.requirements import parameters_in, unmet


class UnknownName(KronsubError):
    """A name that is not a coordinate, velocity or parameter of the system."""


def names(system: KnownSystem) -> dict[str, sympy.Symbol]:
    """Every name of the system: coordinates, velocities, accelerations, parameters, ``t``."""
    out = {"t": TIME}
    for group in (system.coordinates, system.velocities, system.accelerations):
        out.update({s.name: s for s in group})
    out.update({p.name: p.symbol for p in system.parameters})
    return out


def symbol(system: KnownSystem, name: str) -> sympy.Symbol:
    """The system's own symbol called ``name`` (they are ``real=True``: a plain
    ``sympy.Symbol(name)`` is a different symbol)."""
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
    by the system) starts the search for an equilibrium. ``option`` (``"--at"``) places problems
    with the values at ``--at NAME``."""
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
    """A simulated trajectory as arrays: ``t``, ``y = [q; qdot]`` per row, energies."""

    t: np.ndarray
    y: np.ndarray
    columns: tuple[str, ...]  # names of the columns of y
    kinetic_energy: np.ndarray
    potential_energy: np.ndarray
    complete: bool
    message: str
    parameters: dict[str, float]

    @property
    def q(self) -> np.ndarray:
        return self.y[:, : self.y.shape[1] // 2]

    @property
    def qdot(self) -> np.ndarray:
        return self.y[:, self.y.shape[1] // 2:]

    def __getitem__(self, name: str) -> np.ndarray:
        """A column by name: ``run["theta"]``, ``run["t"]``, ``run["total_energy"]``."""
        if name == "t":
            return self.t
        if name in self.columns:
            return self.y[:, self.columns.index(name)]
        extra = {"kinetic_energy": self.kinetic_energy, "potential_energy": self.potential_energy,
                 "total_energy": self.kinetic_energy + self.potential_energy}
        if name in extra:
            return extra[name]
        raise KeyError(f"no column '{name}'; columns: t, {', '.join(self.columns)}, {', '.join(extra)}")

    def to_dataframe(self):
        """A pandas DataFrame indexed by ``t`` (pandas is optional: ImportError without it)."""
        import pandas

        data = {name: self.y[:, i] for i, name in enumerate(self.columns)}
        data.update(kinetic_energy=self.kinetic_energy, potential_energy=self.potential_energy,
                    total_energy=self.kinetic_energy + self.potential_energy)
        return pandas.DataFrame(data, index=pandas.Index(self.t, name="t"))


def _run_values(system: KnownSystem, settings: Mapping[str, object] | None):
    from .simulation.values import resolve

    text = {}
    for name, value in (settings or {}).items():
        if isinstance(value, bool) or not isinstance(value, (str, int, float, np.integer, np.floating)):
            raise ModelError([Problem(None, f"set {name}: expected a number or an expression as text, "
                                            f"got {value!r}")])
        if not isinstance(value, str) and not np.isfinite(value):
            raise ModelError([Problem(None, f"set {name}: {value!r} is not a finite number")])
        text[name] = value if isinstance(value, str) else repr(float(value))
    return resolve(system, dict(system.initial), text)


def simulate(system: KnownSystem, t: float = 10.0, dt: float = 0.01, method: str = "dop853",
             set: Mapping[str, object] | None = None, rtol: float = 1e-10, atol: float = 1e-10,
             dataframe: bool | None = None):
    """Integrate from the model's initial values (``set`` overrides parameters and the
    initial state by name) to ``t``, rows every ``dt``: the arrays of a :class:`Run`, or
    its pandas DataFrame when ``dataframe`` is true (default: when pandas is installed)."""
    from .simulation.run import simulate as run
    from .simulation.table import energies

    values = _run_values(system, set)
    traj = run(system, values, t, dt, method, rtol, atol, progress=False)
    if not traj.complete:
        warnings.warn(f"the run stopped at t = {traj.t_fail:.6g}: {traj.message}; the rows so far are kept")
    T, V = energies(system, traj, np.array(values.parameters))
    columns = tuple(s.name for s in system.coordinates) + tuple(s.name for s in system.velocities)
    result = Run(traj.t, traj.y.reshape(len(traj.t), len(columns)), columns, T, V, traj.complete,
                 traj.message, {p.name: v for p, v in zip(system.parameters, values.parameters)})
    if dataframe is None:
        try:
            import pandas  # noqa: F401
            dataframe = True
        except ImportError:
            dataframe = False
    return result.to_dataframe() if dataframe else result


def sweep(system: KnownSystem, grid: Mapping[str, object] | None = None, sample: Mapping[str, str] | None = None,
          runs: int | None = None, seed: int = 0, t: float = 10.0, dt: float = 0.01, method: str = "dop853",
          set: Mapping[str, object] | None = None, rtol: float = 1e-10, atol: float = 1e-10, *,
          latin: bool = False, scheduler: str | None = None, workers: int | None = None, chunk: int | None = None):
    """Many runs over a grid (``grid``: name -> ``"a:b:n"``, ``"log:a:b:n"`` or a list of values)
    and a sample (``sample``: name -> ``"uniform(a, b)"``, ``"normal(mu, sd)"``,
    ``"loguniform(a, b)"``, ``runs`` draws) of parameters and initial values, on Dask
    (``scheduler``, else a local cluster of ``workers``): a pandas DataFrame of a row per run,
    as the rows ``kronsub sweep`` writes (:mod:`kronsub.sweep`). It holds every row in memory:
    for sweeps larger than memory, the command writes a Parquet dataset a chunk at a time."""
    import os

    import pandas

    from .sweep.axes import read_axes
    from .sweep.driver import ENV_SCHEDULER, execute
    from .sweep.study import DEFAULT_CHUNK, make_job, make_plan

    grids = tuple(f"{name}={spec}" if isinstance(spec, str) else
                  f"{name}=[{', '.join(repr(float(v)) for v in spec)}]" for name, spec in (grid or {}).items())
    samples = tuple(f"{name}={spec}" for name, spec in (sample or {}).items())
    plan = make_plan(*read_axes(grids, samples), runs, seed, latin)
    values = _run_values(system, set)  # checks the fixed values
    settings = {p.name: repr(v) for p, v in zip(system.parameters, values.parameters) if p.name in (set or {})}
    names = [q.name for q in system.coordinates] + [v.name for v in system.velocities]
    settings.update({name: repr(v) for name, v in zip(names, values.y0) if name in (set or {})})
    job = make_job(system, plan, dict(system.initial), settings, method=method, t_end=t, dt=dt, rtol=rtol,
                   atol=atol, chunk=chunk or DEFAULT_CHUNK)
    parts: dict[int, pandas.DataFrame] = {}
    execute(job, range(job.chunks), lambda index, rows: parts.__setitem__(index, pandas.DataFrame(rows)),
            scheduler=scheduler or os.environ.get(ENV_SCHEDULER) or None, workers=workers)
    return pandas.concat([parts[i] for i in sorted(parts)], ignore_index=True)


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

    values = _run_values(system, set)
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
    with :meth:`symbol`, :meth:`simulate`, :meth:`sweep`, :meth:`numeric`, :meth:`linearize` and its Jupyter
    display. The conveniences add no data: a ``System`` goes wherever a ``KnownSystem`` does."""

    @classmethod
    def of(cls, known: KnownSystem) -> System:
        """``known``'s data, with the notebook's conveniences."""
        if isinstance(known, cls):
            return known
        return cls(**{f.name: getattr(known, f.name) for f in dataclasses.fields(KnownSystem)})

    def symbol(self, name: str) -> sympy.Symbol:
        """The system's symbol called ``name`` (kronsub's symbols are ``real=True``)."""
        return symbol(self, name)

    def simulate(self, t: float = 10.0, dt: float = 0.01, method: str = "dop853", set=None, **options):
        """Simulate from the model's initial values; see :func:`simulate`."""
        return simulate(self, t, dt, method, set, **options)

    def sweep(self, grid=None, sample=None, runs=None, seed=0, t: float = 10.0, dt: float = 0.01, **options):
        """A row of summaries per run over a grid or a sample (a pandas DataFrame); see :func:`sweep`."""
        return sweep(self, grid, sample, runs, seed, t, dt, **options)

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

    def derive(self, *, cache: bool = True) -> System:
        """The equations of motion by projection onto the subspace (9'), (E), (F)."""
        return System.of(super().derive(cache=cache))


def load(path, *, text: str | None = None, cache: bool = True) -> LoadedModel:
    """Load and validate a model file (see :func:`kronsub.load`)."""
    model = load_model(path, text=text, cache=cache)
    return LoadedModel(**{f.name: getattr(model, f.name) for f in dataclasses.fields(Model)})


__all__ = ["LoadedModel", "NumericSystem", "Run", "System", "UnknownName", "linearize", "load", "names", "numeric",
           "repr_latex", "repr_markdown", "simulate", "split_assignments", "symbol"]
