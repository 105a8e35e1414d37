"""Python's cyclic garbage collector paused while a bounded step builds many objects."""
from __future__ import annotations

import atexit
import contextlib
import gc


@contextlib.contextmanager
def collector_paused():
    """Run the block with the cyclic collector off; reference counting still frees memory.

    Loading and deriving a model build sympy expressions by the hundred thousand and almost
    no cycles (a 20-link chain: a few hundred objects in cycles), and every collection they
    trigger walks the young objects again, every full one each object alive, sympy's caches
    included: 10-25 % of deriving the 20- and 50-link chains, and about half of reading the
    cached 20-link chain (benchmarks/derive_chain.py). The collector is turned back on
    afterwards only if it was on, so pauses nest; what is left in cycles goes at its next run.
    """
    was_on = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        if was_on:
            gc.enable()


@contextlib.contextmanager
def preparation():
    """A command's preparation (importing SymPy, loading, deriving, emitting and compiling the
    model) with the collector paused, and what it leaves alive set aside (``gc.freeze``) when it
    ends, until the command ends (:func:`released`, which ``run_command`` calls): the collections
    of the command's rest (a run's rows) walk their own objects only, and turning the collector
    back on walks none of the modules, SymPy expressions and cache entries made before, nor does
    any collection while they are made. Nothing is set aside when something else froze objects
    already (their owner would find them given back)."""
    was_on = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        if _SET_ASIDE or not gc.get_freeze_count():
            gc.freeze()
            _SET_ASIDE[:] = [True]
        if was_on:
            gc.enable()


def released() -> None:
    """Give what :func:`preparation` set aside back to the collector (a command's end)."""
    if _SET_ASIDE:
        _SET_ASIDE.clear()
        gc.unfreeze()


_SET_ASIDE: list[bool] = []


def frozen_at_exit() -> None:
    """Freeze every object left at interpreter exit (``gc.freeze``), once per process: the
    collections the interpreter runs while it shuts down then skip them, and reference
    counting alone frees them. After a command that derived and emitted a model those passes
    would walk every sympy expression and cache entry still alive to find the few cycles the
    process drops anyway. The other exit handlers run as before; an object in a cycle is not
    finalised, so a command closes its outputs itself (as :mod:`kronsub.atomic` does)."""
    if not _FROZEN:
        _FROZEN.append(True)
        atexit.register(gc.freeze)


_FROZEN: list[bool] = []


__all__ = ["collector_paused", "frozen_at_exit", "preparation", "released"]
