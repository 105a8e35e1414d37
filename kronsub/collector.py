"""Python's cyclic garbage collector paused while a bounded step builds many objects."""
from __future__ import annotations

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


__all__ = ["collector_paused"]
