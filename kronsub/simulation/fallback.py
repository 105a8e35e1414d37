"""The generated numpy module, which stands in for the compiled C when there is no compiler:
the right-hand side ``ydot = [qdot; Mbar^-1 (fbar - hbar)]`` and the energies ``T``, ``V`` (24)."""
from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING, Any

import numpy as np

from ..core.known_system import KnownSystem
from ..emitters.code import emit_python
from ..emitters.escape import python_string
from .failure import Singular

if TYPE_CHECKING:
    from ..core.constraints import Intermediates
    from ..model.scenes import Outputs

Module = dict[str, Any]
"""The generated numpy module's namespace: ``rhs``, ``kinetic_energy``, ``potential_energy``, ..."""

__all__ = ["Module", "module_energies", "numpy_module", "numpy_rhs", "numpy_rhs_of"]


def numpy_module(system: KnownSystem, outputs: Outputs | None = None) -> Module:
    """The generated numpy module, loaded from its text (our own generated code)."""
    namespace: Module = {}
    (generated,) = emit_python(system, "model", outputs=outputs)
    exec(compile(generated.text, f"<kronsub model {python_string(system.name)}>", "exec"), namespace)
    return namespace


def numpy_rhs_of(module: Module, param: np.ndarray) -> Callable[[float, np.ndarray], np.ndarray]:
    """``ydot = f(t, y)`` of ``module`` at ``param``; a singular ``Mbar`` raises :class:`.failure.Singular`."""
    rhs = module["rhs"]

    def f(t, y):
        try:
            return rhs(t, y, param)
        except np.linalg.LinAlgError as exc:
            raise Singular(t, y) from exc

    return f


def module_energies(module: Module, t: np.ndarray, Y: np.ndarray, param: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(T, V)`` (24) at each row of ``Y`` at the times ``t``."""
    T = np.array([module["kinetic_energy"](y, param) for y in Y])
    V = np.array([module["potential_energy"](ti, y, param) for ti, y in zip(t, Y)])
    return T, V


def numpy_rhs(system: KnownSystem, param: np.ndarray, outputs: Outputs | None = None,
              constrained: Intermediates | None = None,
              tol: float = 1e-12) -> Callable[[float, np.ndarray], np.ndarray]:
    """:func:`numpy_rhs_of` the module of ``system``; with implicit constraints, its Newton's method
    starts from ``constrained``'s guess at tolerance ``tol``."""
    module = numpy_module(system, outputs)
    if constrained is not None:
        from .constrained import configure_module

        configure_module(module, constrained.guess, tol)
    return numpy_rhs_of(module, param)
