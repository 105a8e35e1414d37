"""The integration methods: one table, read by ``simulate``, ``accuracy`` and their help texts.

Each :class:`Method` says which engine runs it, its order, whether it takes fixed steps of
``--dt`` or adapts its step to ``--rtol``/``--atol``, whether it runs closed loops (implicit
constraints (25)-(29): the dependent coordinates come from Newton's method inside the
right-hand side, so a method needing explicit equations, a Taylor series, cannot), the
floating-point precision it computes in, the method run in its place where it cannot run, and a
one-line summary. Its engine (:mod:`.engines`, one interface) runs it for both commands. The schema's enum of a
scene's ``method`` (``model/schema.json``) lists :data:`SIMULATE` (tested equal).
"""
from __future__ import annotations

from dataclasses import dataclass

__all__ = ["ENGINES", "MEASURED", "METHODS", "Method", "SIMULATE", "by_engine", "help_text", "unknown_method"]

ENGINES = ("c", "taylor", "scipy", "heyoka", "extended")
"""The engines, in the order ``accuracy`` lists their methods: the compiled C integrators
(:mod:`.native`), a Taylor integrator generated as C for the model (:mod:`.taylor_c`), scipy's
solvers calling the compiled right-hand side, heyoka (optional), extrapolation in extended
precision C (:mod:`.extended`, ``accuracy`` only)."""


@dataclass(frozen=True)
class Method:
    """One integration method.

    ``order``: the order of its error (None: variable, chosen per step or per tolerance);
    ``fixed_step``: it steps ``--dt`` at a time (else adaptive to the tolerances);
    ``closed_loops``: it runs systems with implicit constraints; ``precision``: ``double``,
    ``long`` (long double) or ``quad`` (``_Float128``); ``simulate``: a method of
    ``simulate`` (else of ``accuracy`` only); ``fallback``: the method ``simulate`` runs
    instead where this one cannot, when the model did not compile or to watch an event
    between rows (None: none is needed)."""

    name: str
    engine: str
    order: int | None
    fixed_step: bool
    closed_loops: bool
    precision: str
    summary: str
    simulate: bool = True
    fallback: str | None = None


METHODS: dict[str, Method] = {
    m.name: m
    for m in (
        Method(name="dop853", engine="c", order=8, fixed_step=False, closed_loops=True, precision="double",
               fallback="DOP853",
               summary="Dormand-Prince 8(5,3), adaptive, dense output at --dt; wholly in C (default: accurate and "
                       "fast for smooth non-stiff problems)"),
        Method(name="gauss4", engine="c", order=4, fixed_step=True, closed_loops=True, precision="double",
               fallback="DOP853",
               summary="2-stage Gauss-Legendre, fixed step --dt, symplectic in (q, p = Mbar qdot); for long "
                       "conservative runs: energy error stays bounded instead of drifting (with implicit "
                       "constraints: order 4 in (q, qdot))"),
        Method(name="rk4", engine="c", order=4, fixed_step=True, closed_loops=True, precision="double",
               fallback="DOP853",
               summary="the classical Runge-Kutta method, fixed step --dt, wholly in C: the cheap baseline"),
        Method(name="RK45", engine="scipy", order=5, fixed_step=False, closed_loops=True, precision="double",
               summary="scipy's Dormand-Prince 5(4) calling the compiled right-hand side"),
        Method(name="DOP853", engine="scipy", order=8, fixed_step=False, closed_loops=True, precision="double",
               summary="scipy's DOP853 calling the compiled right-hand side"),
        Method(name="Radau", engine="scipy", order=5, fixed_step=False, closed_loops=True, precision="double",
               summary="scipy's implicit Radau IIA (order 5): stiff problems (stiff springs, dampers)"),
        Method(name="LSODA", engine="scipy", order=None, fixed_step=False, closed_loops=True, precision="double",
               summary="scipy's LSODA: switches between stiff and non-stiff automatically"),
        Method(name="taylor", engine="taylor", order=None, fixed_step=False, closed_loops=False, precision="double",
               summary="a Taylor integrator generated as C for the model, order 2 ceil(ln(1/rtol)/4)+4 (compiled "
                       "per order): the high-accuracy end, explicit equations only; tolerance --rtol"),
        Method(name="heyoka", engine="heyoka", order=None, fixed_step=False, closed_loops=False, precision="double",
               summary="heyoka's Taylor integrator (optional extra kronsub[heyoka]): the high-accuracy end, for "
                       "small systems; tolerance --rtol"),
        Method(name="gbs-long", engine="extended", order=None, fixed_step=False, closed_loops=False,
               precision="long", simulate=False,
               summary="Gragg-Bulirsch-Stoer extrapolation in the generated C in long double (accuracy only)"),
        Method(name="gbs-quad", engine="extended", order=None, fixed_step=False, closed_loops=False,
               precision="quad", simulate=False,
               summary="Gragg-Bulirsch-Stoer extrapolation in the generated C in _Float128 (accuracy only)"),
    )
}

SIMULATE: tuple[str, ...] = tuple(name for name, m in METHODS.items() if m.simulate)
"""The methods of ``simulate`` (and of a scene's ``method``), in the table's order."""

def by_engine(engine: str) -> tuple[str, ...]:
    """The names of the methods ``engine`` runs, in the table's order."""
    return tuple(name for name, m in METHODS.items() if m.engine == engine)


MEASURED: tuple[str, ...] = tuple(name for engine in ENGINES for name in by_engine(engine))
"""The methods of ``accuracy``, engine by engine in the order of :data:`ENGINES`."""

_RUNS_IN = {"c": "C", "taylor": "C generated for the model", "scipy": "scipy", "heyoka": "heyoka, optional extra",
            "extended": "C in extended precision"}


def unknown_method(method: str, names: tuple[str, ...] = SIMULATE) -> str:
    """The message for a method that is not among ``names``."""
    return f"unknown method '{method}'; choose one of: {', '.join(names)}"


def _described(m: Method) -> str:
    traits = [_RUNS_IN[m.engine], "fixed step" if m.fixed_step else "adaptive"]
    if m.order is not None:
        traits.append(f"order {m.order}")
    if not m.closed_loops:
        traits.append("explicit equations only")
    if m.precision != "double":
        traits.append("long double" if m.precision == "long" else "_Float128")
    return f"{m.name} ({', '.join(traits)})"


def help_text(names: tuple[str, ...] = SIMULATE) -> str:
    """``name (runs in, fixed step or adaptive, order, ...)`` for each of ``names``, from the table."""
    return "; ".join(_described(METHODS[name]) for name in names) + "."
