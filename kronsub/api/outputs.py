"""What the commands write, from the notebook: generated code, the accuracy experiment and
its table, the equations with their reactions, and the displays of Jupyter.

Thin wrappers of the code the commands run (``kronsub codegen``, ``accuracy``,
``derive --reactions``).
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Mapping

from ..core.known_system import KnownSystem
from ..core.projection_work import numeric_route_advice
from ..emitters.escape import C_IDENTIFIER
from ..errors import KronsubError
from ..model.model import Model
from .runs import model_file, scene_of, settings_text

__all__ = ["Accuracy", "C_IDENTIFIER", "accuracy", "accuracy_plan", "code_files", "codegen", "reactions",
           "repr_latex", "repr_markdown"]


def code_files(system: KnownSystem, stem: str, lang: str = "c", *, prefix: str = "ks", precision: str = "double",
               source: str | None = None, jacobian: bool = False) -> list[tuple[str, str]]:
    """``(file name, text)`` of the generated code (what ``kronsub codegen`` writes): C (header +
    source, in ``precision``: double, long or quad) or a numpy module (``lang="python"``), with
    the scene's outputs; ``source`` names the model file in the files' heads; ``jacobian`` (C):
    with ``<prefix>_jacobian``, the exact ``d ydot/dy``."""
    from ..emitters.code import LANGUAGES

    if lang not in LANGUAGES:
        raise KronsubError(f"unknown language '{lang}'; choose one of {', '.join(LANGUAGES)}")
    if not C_IDENTIFIER.fullmatch(prefix):
        raise KronsubError(f"prefix {prefix!r} is not a C identifier (letters, digits and _, not starting with a digit)")
    if precision not in ("double", "long", "quad") or precision != "double" and lang != "c":
        raise KronsubError(f"precision {precision!r}: double for every language, long or quad for C")
    scene = scene_of(system)
    outputs = scene.outputs if scene is not None else None
    source = model_file(system) or "" if source is None else source
    files = []
    if jacobian and lang != "c":
        raise KronsubError("the exact Jacobian is generated in C only (lang='c')")
    options = {"jacobian": True} if jacobian else {}
    with numeric_route_advice(system):  # a budget spent on the projection onto the speeds says where to go
        for generated in LANGUAGES[lang](system, stem, source=source, prefix=prefix, outputs=outputs, **options):
            text = generated.text
            if precision != "double":
                from ..simulation.extended import prelude, retype

                text = prelude(precision) + retype(text, precision)
            files.append((generated.name, text))
    return files


def codegen(system: KnownSystem, folder=".", lang: str = "c", *, name: str | None = None, prefix: str = "ks",
            precision: str = "double", jacobian: bool = False) -> list[Path]:
    """Write the generated code of ``system`` into ``folder`` (created when missing), as
    ``kronsub codegen`` does; ``name`` is the stem of the files (default: the model file's);
    ``jacobian`` as for :func:`code_files`.
    The paths written, in order.

    >>> import tempfile
    >>> import kronsub
    >>> system = kronsub.load("models/hoffmann/system1.yaml").derive(scene="free")
    >>> with tempfile.TemporaryDirectory() as folder:
    ...     [p.name for p in system.codegen(folder, "python")]
    ['system1.py']
    """
    from ..atomic import write_atomically

    model = getattr(system, "model", None)
    stem = name or (Path(model.path).stem if model is not None else "model")
    folder = Path(folder)
    files = code_files(system, stem, lang, prefix=prefix, precision=precision, jacobian=jacobian)
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
        from ..simulation import accuracy_report

        return accuracy_report.markdown(self.measurement, target)

    def to_csv(self) -> str:
        """The CSV of ``--output``: one row per method and tolerance."""
        from ..simulation import accuracy_report

        return accuracy_report.work_precision_csv(self.measurement)

    def metadata(self, target: float | None = None, csv: str | None = None) -> dict:
        """The metadata of ``--meta``."""
        from ..simulation import accuracy_report

        model = self.model
        return accuracy_report.metadata(self.measurement, model_file=Path(model.path).as_posix() if model else None,
                                        source=model.source if model else None, uses=model.uses if model else (),
                                        scene=self.scene, methods=self.methods, tolerances=self.tolerances,
                                        target=target, csv=csv)

    def plot(self, path, target: float | None = None) -> None:
        """The work-precision PNG of ``--plot`` (needs matplotlib)."""
        from ..simulation import accuracy_report

        accuracy_report.plot(self.measurement, path, target)


TOLERANCES = "1e-4:1e-14"
"""The default grid of tolerances of an accuracy experiment (``--tolerances``)."""


def accuracy_plan(methods="all", tolerances=None, *, quick: bool = False,
                  precision: str = "double") -> tuple[tuple[str, ...], tuple[float, ...]]:
    """The methods and tolerances of an accuracy experiment, read as ``--methods``,
    ``--tolerances``, ``--quick`` and ``--precision`` are (text, or sequences); ``quick`` thins
    the default grid (``tolerances`` None: :data:`TOLERANCES`) and keeps tolerances given."""
    from ..simulation import accuracy as acc

    chosen = acc.parse_methods(methods if isinstance(methods, str) else ",".join(methods))
    if precision != "double" and f"gbs-{precision}" not in chosen:
        chosen = chosen + (f"gbs-{precision}",)
    thin = quick and tolerances is None
    tolerances = TOLERANCES if tolerances is None else tolerances
    grid = acc.parse_tolerances(tolerances) if isinstance(tolerances, str) else tuple(float(x) for x in tolerances)
    return chosen, acc.quick_tolerances(grid) if thin else grid


def accuracy(system: KnownSystem, t: float = 10.0, methods="all", tolerances=None, *, quick: bool = False,
             digits: int | None = None, precision: str = "double", set: Mapping[str, object] | None = None,
             keep_interrupted: bool = False) -> Accuracy:
    """The experiment of ``kronsub accuracy``: each method at each tolerance run to ``t`` from
    the model's initial values (``set`` overrides them), its error against a high-precision
    reference and its time. ``keep_interrupted``: an interrupt (Ctrl-C, SIGTERM) once the
    reference is computed ends the experiment with the points measured so far
    (``measurement.interrupted``: its signal) instead of raising.

    >>> import kronsub
    >>> system = kronsub.load("models/hoffmann/system1.yaml").derive(scene="free")
    >>> result = system.accuracy(t=0.2, methods="dop853", tolerances="1e-6", quick=True)
    >>> [(p.method, p.setting) for p in result.measurement.points]
    [('dop853', 'tol 1e-06')]
    >>> print(result.markdown().splitlines()[0])
    # Work-precision: System I (scene free), t = 0 .. 0.2
    """
    from ..simulation import accuracy as acc
    from ..simulation.start import starting_values

    chosen, grid = accuracy_plan(methods, tolerances, quick=quick, precision=precision)
    begin = starting_values(system, settings_text(set))  # Newton's tolerance 1e-14: the reference's
    default_digits = 34 if "gbs-quad" in chosen else (16 if quick else 20)
    with numeric_route_advice(system):
        wp = acc.measure(system, begin.values, t, chosen, grid, digits=digits or default_digits, quick=quick,
                         dependent=begin.constrained.guess if begin.constrained is not None else None,
                         keep_interrupted=keep_interrupted)
    scene = scene_of(system)
    return Accuracy(wp, chosen, grid, scene.name if scene is not None else None, getattr(system, "model", None),
                    begin.notes)


def reactions(system: KnownSystem, fmt: str = "markdown") -> str:
    """The text of ``kronsub derive --reactions``: the equations in ``fmt`` (markdown, latex,
    json) with the workless reactions of viewpoint (alpha) as functions of the state."""
    from ..emitters import EMITTERS
    from ..emitters.reactions import with_reactions

    return with_reactions(EMITTERS[fmt](system), system, fmt)


def repr_markdown(system: KnownSystem) -> str:
    """The Markdown of ``kronsub derive`` (Jupyter's ``_repr_markdown_``)."""
    from ..emitters.text import emit_markdown

    return emit_markdown(system)


def repr_latex(system: KnownSystem) -> str:
    """``Mbar qddot + hbar = fbar`` as one display-math block (Jupyter's ``_repr_latex_``).

    Only symbols reach it (never the model's free text)."""
    from ..emitters.report import latex_printer

    show = latex_printer(system.coordinates)
    rows = " \\\\ ".join(f"{show(eq.lhs)} &= {show(eq.rhs)}" for eq in system.equations())
    return "$$\\begin{aligned} " + rows + " \\end{aligned}$$"
