"""The notebook's objects: :func:`load`, the model it gives, and :class:`System`, a derived
system with the conveniences of :mod:`kronsub.api`.
"""
from __future__ import annotations

import dataclasses
from pathlib import Path

import sympy

from ..core.known_system import KnownSystem
from ..core.linearize import Linearization
from ..model.loader import load_model
from ..model.model import Model
from ..model.scenes import derive_scene, select_scene
from .naming import linearize, symbol
from .outputs import Accuracy, accuracy, codegen, reactions, repr_latex, repr_markdown
from .runs import NumericSystem, animate, numeric, simulate
from .sweeps import sweep

__all__ = ["LoadedModel", "System", "load"]


class System(KnownSystem):
    """A derived system as a notebook sees it: the :class:`KnownSystem`'s data (``mass_matrix``
    is ``Mbar = Cᵀ M C`` (9'), ``velocity_terms``, ``forces``, ``coordinates``, energies...),
    with :meth:`symbol`, :meth:`simulate`, :meth:`sweep`, :meth:`numeric`, :meth:`linearize` and its Jupyter
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

    def sweep(self, grid=None, sample=None, runs=None, seed=0, t: float = 10.0, dt: float = 0.01, **options):
        """A row of summaries per run over a grid or a sample (a pandas DataFrame, or with ``output``
        the Parquet dataset's folder); see :func:`~.sweeps.sweep`."""
        return sweep(self, grid, sample, runs, seed, t, dt, **options)

    def numeric(self, set=None) -> NumericSystem:
        """Compiled ``rhs``, ``mass_matrix``, energies...; see :func:`numeric`."""
        return numeric(self, set)

    def linearize(self, at=None, inputs=(), *, symbolic: bool = False) -> Linearization:
        """``A``, ``B`` about an operating point; see :func:`linearize`."""
        model = self.model
        return linearize(self, at, inputs, symbolic=symbolic,
                         drive=model.locations.get("drive") if model is not None else None)

    def _repr_markdown_(self) -> str:
        return repr_markdown(self)

    def _repr_latex_(self) -> str:
        return repr_latex(self)


class LoadedModel(Model):
    """A model as :func:`load` gives it: a :class:`~kronsub.model.model.Model` whose
    :meth:`derive` returns a :class:`System`."""

    def derive(self, *, scene: str | bool | None = None, cache: bool = True) -> System:
        """The equations of motion by projection onto the subspace (9'), (E), (F), of the
        ``scene`` called so (default: the model's only scene if it has exactly one, else every
        effect; the rule of ``--scene``; ``scene=False``: every effect, the whole model). An
        unknown scene is a ``ModelError`` naming the valid ones.

        >>> import kronsub
        >>> system = kronsub.load("models/hoffmann/system1.yaml").derive(scene="free")
        >>> system.name, [q.name for q in system.coordinates]
        ('System I (scene free)', ['theta', 'phi'])
        >>> sorted(system.effect_forces)
        ['gravity']
        """
        chosen = None if scene is False else select_scene(self, scene)
        system = super().derive(cache=cache) if chosen is None else derive_scene(self, chosen, cache=cache)
        return System.of(system, self, chosen)


def load(path, *, text: str | None = None, cache: bool = True) -> LoadedModel:
    """Load and validate a model file (see :func:`kronsub.load`)."""
    model = load_model(path, text=text, cache=cache)
    return LoadedModel(**{f.name: getattr(model, f.name) for f in dataclasses.fields(Model)})
