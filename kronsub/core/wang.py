"""Wang's multivariate factorization given only the variables it needs.

``sympy.factor`` of a polynomial in many variables ends in ``dmp_zz_wang`` (Wang's
Enhanced Extended Zassenhaus algorithm), whose Hensel lifting over randomly chosen
evaluation points grows steeply with the number of variables: a sum of a spring's and a
damper's forces, 13 terms in 11 variables, took minutes at one seed and 0.05 s at another.
Most of those variables are parameters and velocities that appear to the first power.

A primitive square-free ``f`` of degree one in a variable ``x`` is ``g (a x + b)`` with
``g = gcd(A, B)`` for ``f = A x + B``: ``a x + b`` is irreducible (a factor free of ``x``
would divide both ``a`` and ``b``), and ``g`` is free of ``x``. :func:`peeled` factors so,
variable by variable, and leaves to Wang only what is of higher degree in every variable.
Irreducible factors are unique up to sign, and each is returned as Wang returns it
(primitive, with a positive leading coefficient), so ``sympy.factor`` gives the same result.
"""
from __future__ import annotations

import contextlib

from sympy.polys import factortools
from sympy.polys.densebasic import dmp_from_dict, dmp_ground_LC, dmp_to_dict
from sympy.polys.densearith import dmp_exquo, dmp_neg
from sympy.polys.densetools import dmp_ground_primitive
from sympy.polys.euclidtools import dmp_gcd

from ..budget import charge

_WANG = factortools.dmp_zz_wang


@contextlib.contextmanager
def peeled():
    """Run the block with sympy's ``dmp_zz_wang`` replaced by :func:`factor_sqf`."""
    saved = factortools.dmp_zz_wang
    factortools.dmp_zz_wang = factor_sqf
    try:
        yield
    finally:
        factortools.dmp_zz_wang = saved


def factor_sqf(f, u, K, mod=None, seed=None):
    """The irreducible factors of the primitive square-free ``f`` in ``Z[x_0..x_u]``
    (``dmp_zz_wang``'s contract): the variables of degree one peeled off first."""
    terms = dmp_to_dict(f, u, K)
    charge(len(terms) * (u + 1), "the factorization of an entry's printed form")
    for j in range(u + 1):
        if max(m[j] for m in terms) != 1:
            continue
        linear = {_drop(m, j): c for m, c in terms.items() if m[j] == 1}
        constant = {_drop(m, j): c for m, c in terms.items() if m[j] == 0}
        A, B = dmp_from_dict(linear, u - 1, K), dmp_from_dict(constant, u - 1, K)
        g = dmp_gcd(A, B, u - 1, K)
        h = dmp_exquo(f, dmp_from_dict({_lift(m, j): c for m, c in dmp_to_dict(g, u - 1, K).items()}, u, K),
                      u, K)
        rest = factortools.dmp_zz_factor(g, u - 1, K)[1]
        lifted = [dmp_from_dict({_lift(m, j): c for m, c in dmp_to_dict(p, u - 1, K).items()}, u, K)
                  for p, _ in rest]
        return [_normal(p, u, K) for p in (*lifted, h)]
    return _WANG(f, u, K, mod, seed)


def _drop(monomial: tuple, j: int) -> tuple:
    return monomial[:j] + monomial[j + 1:]


def _lift(monomial: tuple, j: int) -> tuple:
    return monomial[:j] + (0,) + monomial[j:]


def _normal(p, u, K):
    """``p`` primitive, with a positive leading coefficient (as Wang returns its factors)."""
    _, p = dmp_ground_primitive(p, u, K)
    return dmp_neg(p, u, K) if K.is_negative(dmp_ground_LC(p, u, K)) else p


__all__ = ["factor_sqf", "peeled"]
