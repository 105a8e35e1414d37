"""The generated numpy module, which stands in for the compiled C when there is no compiler:
the right-hand side ``ydot = [qdot; Mbar^-1 (fbar - hbar)]`` and the energies ``T``, ``V`` (24)."""
from __future__ import annotations

import numpy as np

from ..core.known_system import KnownSystem
from ..emitters.code import emit_python
from ..emitters.escape import python_string
from .failure import Singular

__all__ = ["numpy_module", "numpy_rhs_of", "module_energies", "numpy_rhs"]


def numpy_module(system: KnownSystem, outputs=None):
    """The generated numpy module, loaded from its text (our own generated code)."""
    namespace: dict = {}
    (generated,) = emit_python(system, "model", outputs=outputs)
    exec(compile(generated.text, f"<kronsub model {python_string(system.name)}>", "exec"), namespace)
    return namespace


def numpy_rhs_of(module, param):
    rhs = module["rhs"]

    def f(t, y):
        try:
            return rhs(t, y, param)
        except np.linalg.LinAlgError as exc:
            raise Singular(t, y) from exc

    return f


def module_energies(module, t, Y, param):
    T = np.array([module["kinetic_energy"](y, param) for y in Y])
    V = np.array([module["potential_energy"](ti, y, param) for ti, y in zip(t, Y)])
    return T, V


def numpy_rhs(system, param, outputs=None, constrained=None, tol=1e-12):
    module = numpy_module(system, outputs)
    if constrained is not None:
        from .constrained import configure_module

        configure_module(module, constrained.guess, tol)
    return numpy_rhs_of(module, param)
