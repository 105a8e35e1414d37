"""A matrix whose entries are built when first read.

A system under velocity constraints is used in its speeds: ``Mbar = C^T M C`` (9'), (D) in the
coordinates ``x`` is a step on the way, which a linearisation about a steady motion does not
take (it projects numerically from the primitive and ``C``). Its entries, and their printed
forms, are built when something reads them: a printed derivation, generated code, a run.
"""
from __future__ import annotations

from collections.abc import Callable

import sympy

from .sympy_internals import matrix_fromrep


class DeferredMatrix(sympy.MutableDenseMatrix):
    """A ``rows x cols`` matrix given by ``build()``, called on the first read of an entry (any
    use of the matrix but its shape). Every result of an operation on it is a plain matrix: its
    class ranks below SymPy's own, so an operation with one converts it (building it), never the
    other way round."""

    _class_priority = 3.5  # below MutableDenseMatrix's 4

    def __new__(cls, *args):
        if len(args) != 3 or not callable(args[2]):  # what SymPy converts to this class: a plain matrix
            return sympy.Matrix(*args)
        rows, cols, build = args
        obj = object.__new__(cls)
        obj.rows, obj.cols = rows, cols
        obj.__dict__["_build"] = build
        return obj

    def __getattr__(self, name):  # only for what the instance does not hold yet: its entries
        if name != "_rep":
            raise AttributeError(name)
        built = self.__dict__["_build"]()
        if built.shape != (self.rows, self.cols):
            raise ValueError(f"a deferred {self.rows} x {self.cols} matrix was built {built.rows} x {built.cols}")
        self._rep = sympy.Matrix(built)._rep
        return self._rep

    @classmethod
    def _fromrep(cls, rep):
        return matrix_fromrep(sympy.MutableDenseMatrix, rep)

    def __reduce__(self):
        """Built: a plain matrix of the entries. Not built yet: a deferred matrix still, its build
        with it (a closure, which cloudpickle carries, as Dask sends a sweep's system to its
        workers), so that sending it does not build it."""
        if self.built:
            return sympy.Matrix, (self.rows, self.cols, list(self))
        return DeferredMatrix, (self.rows, self.cols, self.__dict__["_build"])

    @property
    def built(self) -> bool:
        """Whether the entries have been built."""
        return "_rep" in self.__dict__


class Once:
    """A function of no arguments whose result is computed on the first call and kept (as
    ``functools.cache`` keeps it, but carried by cloudpickle, with its function, while not
    computed yet: what a :class:`DeferredMatrix` not built yet is built from)."""

    def __init__(self, build: Callable[[], object]):
        self.build = build

    def __call__(self):
        if "result" not in self.__dict__:
            self.result = self.build()
        return self.result


def pending(m) -> bool:
    """Whether ``m`` is a :class:`DeferredMatrix` whose entries are not built yet."""
    return isinstance(m, DeferredMatrix) and not m.built


__all__ = ["DeferredMatrix", "Once", "pending"]
