"""A run's starting values: the one route every command and the notebook take.

The values come from the derived system: its parameters' values and its ``initial``
(:func:`kronsub.model.scenes.derive_scene` puts a scene's values over the model's). The
settings (``--set NAME=VALUE``, ``--at``, or the ``set=`` of :mod:`kronsub.api`) override
them by name. For a closed loop the result is projected onto the constraints (26)-(29):
the dependent coordinates by Newton's method with the independent ones held, the
velocities onto the tangent space ``G ydot = 0`` (:func:`.constrained.project_initial`). In
speeds, the coordinates held by configuration constraints are put on them (:mod:`.held`).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Mapping

from ..core.constraints import Intermediates
from ..core.known_system import KnownSystem
from .constrained import project_initial, split_settings
from .held import hold_start
from .values import RunValues, resolve

__all__ = ["Start", "starting_values"]


@dataclass(frozen=True)
class Start:
    """Where a run starts: ``values`` (parameters and ``y0 = [q0; qdot0]``), for a closed loop
    ``constrained`` (the dependent coordinates there, for the run to follow their branch), the
    ``notes`` on the corrections the projection made."""

    values: RunValues
    constrained: Intermediates | None = None
    notes: tuple[str, ...] = ()


def starting_values(system: KnownSystem, settings: Mapping[str, str] | None = None, *,
                    tolerance: float = 1e-14, initial: Mapping | None = None) -> Start:
    """The starting values of a run of ``system``: ``system.initial`` (or ``initial``) and its
    parameters' values, overridden by ``settings`` (``{name: text}``, constant expressions read
    by the whitelisted parser), projected onto the constraints of a closed loop to Newton's
    ``tolerance`` (in speeds, the coordinates that configuration constraints hold beside the
    velocity constraints put on them: :func:`.held.hold_start`). Every problem with the settings
    is reported at once (a ``ModelError``)."""
    start = dict(system.initial) if initial is None else dict(initial)
    settings = {system.symbol_name(name): text for name, text in (settings or {}).items()}  # i_q as q_dot
    if system.implicit is None:
        values, notes = hold_start(system, resolve(system, start, settings), settings)  # held by constraints, in speeds
        return Start(values, notes=tuple(notes))
    independent, dependent = split_settings(system, settings)
    values = resolve(system, start, independent)
    values, notes, constrained = project_initial(system, start, dependent, values, tolerance)
    return Start(values, constrained, tuple(notes))
