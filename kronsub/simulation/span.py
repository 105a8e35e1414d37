"""A run's span, step and method: each one given, else the scene's, else the default."""
from __future__ import annotations

__all__ = ["ANIMATION_DEFAULTS", "T_END", "run_span"]

T_END = 10.0
"""The end time of a run when neither the call nor the scene gives one (every command, the API)."""

ANIMATION_DEFAULTS = (T_END, 0.02, "dop853")
"""``t_end``, ``dt``, ``method`` of an animation without a scene's."""


def run_span(system, t: float | None = None, dt: float | None = None, method: str | None = None,
             defaults: tuple[float, float, str] = (T_END, 0.01, "dop853")) -> tuple[float, float, str]:
    """``(t_end, dt, method)`` of a run: each one given, else the scene's (``system.scene``, a
    :class:`~kronsub.api.System`'s), else ``defaults``."""
    scene = getattr(system, "scene", None)

    def pick(given, own, default):
        if given is not None:
            return given
        return own if own is not None else default

    return (pick(t, scene and scene.t_end, defaults[0]), pick(dt, scene and scene.dt, defaults[1]),
            pick(method, scene and scene.method, defaults[2]))
