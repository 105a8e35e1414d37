"""The names kronsub makes may not be names of the model.

Every symbol of a model lives in one namespace: its parameters (with those a known system
used as a component brings along), its generalized coordinates, the primitive coordinates of
its components, and the names kronsub makes from each coordinate ``q``: the velocity
``q_dot`` (``dx/dt`` in the paper's (7), (E)) and the acceleration ``q_ddot`` of (10'). A model
name equal to a made one would silently be the same symbol: a parameter ``q_dot`` beside a
coordinate ``q`` would replace the velocity (a damper then damps nothing), and coordinates
``a`` and ``a_dot`` would be one state twice. So such a model is refused, naming both.

Names inside generated code cannot clash with model names, and are not checked here: the
emitters never write a model name as an identifier. Every parameter, coordinate and velocity
becomes an array slot (``param[i]``, ``q[i]``, ``qd[i]``, ``pre[i]``; see
:func:`kronsub.emitters.numeric.prepare`), so the common-subexpression temporaries, function
arguments (``q``, ``qd``, ``param``, ``pre``, ``M``, ``r``, ``t``, ``y``...), libm and numpy
functions and the keywords of C and Python are free for the code; model names appear only in
comments and strings, through :mod:`kronsub.emitters.escape`.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Iterable

from ..errors import Location, Problem

SUFFIXES = (("_dot", "velocity"), ("_ddot", "acceleration"))


@dataclass(frozen=True)
class Declared:
    """A name the model declares: ``what`` it is (``parameter``, ``coordinate``), whose, and where."""

    name: str
    what: str
    location: Location | None
    owner: str = ""  # e.g. "component 'bob'"

    def __str__(self) -> str:
        return f"{self.what} '{self.name}'" + (f" of {self.owner}" if self.owner else "")


def generated_name_clashes(declared: Iterable[Declared], coordinates: Iterable[Declared]) -> list[Problem]:
    """One problem per declared name that is the velocity or acceleration name of a coordinate."""
    made: dict[str, tuple[str, Declared]] = {}
    for coordinate in coordinates:
        for suffix, meaning in SUFFIXES:
            made.setdefault(coordinate.name + suffix, (meaning, coordinate))
    problems = []
    for item in declared:
        if item.name not in made:
            continue
        meaning, coordinate = made[item.name]
        where = f" (at {coordinate.location})" if coordinate.location is not None else ""
        problems.append(Problem(
            item.location,
            f"{item} has the name kronsub gives the {meaning} of {coordinate}{where}",
            f"rename {item}: the velocity of a coordinate `x` is `x_dot`, its acceleration "
            "`x_ddot`"))
    return problems


__all__ = ["Declared", "SUFFIXES", "generated_name_clashes"]
