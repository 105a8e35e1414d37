"""Python's cyclic garbage collector paused while a bounded step builds many objects."""
from __future__ import annotations

import contextlib
import gc


@contextlib.contextmanager
def collector_paused():
    """Run the block with the cyclic collector off; reference counting still frees memory.

    Reading a cached known system builds tens of thousands of sympy nodes, none of them in a
    cycle, and every full collection they trigger walks each object alive, sympy's caches
    included: about half the time of reading the 20-link chain (benchmarks/derive_chain.py).
    The collector is turned back on afterwards only if it was on, so pauses nest.
    """
    was_on = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        if was_on:
            gc.enable()
