"""The current: the velocity of a charge coordinate, under a name of its own.

A branch of a network is a primitive system whose coordinate is its charge ``q``; the
velocity ``dq/dt`` of that coordinate (the paper's ``dx/dt``, (7)) is the branch current.
kronsub prints and reads it as a current, ``i_a`` for the charge ``qa``, where a mechanical
coordinate ``x`` has the velocity ``x_dot``, and its rate ``di/dt`` (the charge's acceleration)
``i_a_dot``. The symbol is the same (``qa_dot``, made by
:func:`.symbols.velocity_symbol`): only its printed name differs, so the derivation and the
generated code are those of any coordinate.
"""
from __future__ import annotations

from typing import Mapping

import sympy

from .symbols import acceleration_symbol, symbol, velocity_symbol

CHARGE_PREFIX = "q"
CURRENT_PREFIX = "i"


def current_name(charge: str) -> str:
    """The name of the current of the charge coordinate ``charge``: a leading ``q`` (and the
    ``_`` after it) becomes ``i_``: ``qa`` -> ``i_a``, ``q1`` -> ``i_1``, ``q_L`` -> ``i_L``,
    ``q`` -> ``i``; any other name ``x`` (``armature``, ``q_``) gives ``i_x``."""
    if charge == CHARGE_PREFIX:
        return CURRENT_PREFIX
    rest = charge[len(CHARGE_PREFIX):] if charge.startswith(CHARGE_PREFIX) else ""
    rest = rest[1:] if rest.startswith("_") else rest
    return f"{CURRENT_PREFIX}_{rest or charge}"


def printed_velocities(currents: Mapping[str, str]) -> dict[sympy.Symbol, str]:
    """The velocity and acceleration symbols of the charges ``currents`` names (charge name ->
    current name) with their printed names: the current ``i_a`` and its rate ``i_a_dot``."""
    out = {}
    for q, name in currents.items():
        velocity = velocity_symbol(symbol(q))
        if name != velocity.name:
            out[velocity] = name
            out[acceleration_symbol(symbol(q))] = rate_name(name)
    return out


def rate_name(current: str) -> str:
    """The name of a current's rate ``di/dt`` (the charge's acceleration): ``i_a`` -> ``i_a_dot``."""
    return f"{current}_dot"


__all__ = ["current_name", "printed_velocities", "rate_name"]
