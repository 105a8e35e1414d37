"""sympy's own random numbers drawn from a fixed seed around the calls that use them, and
Wang's factorization given only the variables it needs (:mod:`.wang`)."""
from __future__ import annotations

import contextlib
import functools

from sympy.core import random as sympy_random

from .sympy_internals import assumptions_rng
from .wang import peeled

SEED = 20261124
"""The seed each such call starts from."""


@contextlib.contextmanager
def sympy_seeded():
    """Run the block with sympy's random generators seeded with `SEED`, then give them back
    their state.

    Wang's multivariate factorization (under ``sympy.factor``, ``simplify`` and ``trigsimp``)
    tries evaluation points drawn at random: the factors are the same whatever they are, the
    time is not. Unseeded, the same reaction of a spring on a spherical pendulum took 2 s in
    four runs and over 5 minutes in the fifth; seeded, every run takes the path of the first.
    The variables of degree one are peeled off before Wang's algorithm (:func:`.wang.peeled`),
    whose time at any seed grows steeply with the number of variables.
    """
    states = sympy_random.rng.getstate(), assumptions_rng().getstate()
    sympy_random.seed(SEED)
    try:
        with peeled():
            yield
    finally:
        sympy_random.rng.setstate(states[0])
        assumptions_rng().setstate(states[1])


def seeded(function):
    """`sympy_seeded` around every call of ``function``."""
    @functools.wraps(function)
    def wrapper(*args, **kwargs):
        with sympy_seeded():
            return function(*args, **kwargs)
    return wrapper


__all__ = ["SEED", "seeded", "sympy_seeded"]
