"""The kind of energy each effect stores or takes, for a run's split by kind
(:mod:`kronsub.simulation.power`).

An effect's potential ``V`` (17) is electric when it is a capacitor's ``q^2/(2C)``, else
mechanical; its generalized force dissipates when it comes from Rayleigh's function (a
resistor's ``R i^2/2``, a damper's, a textbook component's ``dissipation:``). A known system
used as a component brings the kinds of its own effects, so a model built from machines is
split as the machines are.
"""
from __future__ import annotations

from typing import Mapping, Sequence

from ..core.primitive import Primitive
from ..effects.electrical import Capacitor, Resistor
from ..effects.elements import Damper, TorsionalDamper

ELECTRIC = "electric"
DISSIPATIVE = "dissipative"
KINDS = {Capacitor: ELECTRIC, Resistor: DISSIPATIVE, Damper: DISSIPATIVE, TorsionalDamper: DISSIPATIVE}


def effect_kinds(primitive: Primitive, effects: Sequence) -> Mapping[str, str]:
    """The kind of every effect that has one, by its label (``part.effect`` for a known
    system's or a textbook component's own, :func:`kronsub.core.subspace.effect_labels`)."""
    kinds = {f"{part.name}.{label}": kind for part in primitive.parts for label, kind in part.effect_kinds.items()}
    for effect in effects:
        kind = KINDS.get(type(effect))
        if kind is not None:
            kinds[effect.name] = kind
    return kinds


__all__ = ["DISSIPATIVE", "ELECTRIC", "KINDS", "effect_kinds"]
