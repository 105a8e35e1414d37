"""The engine of ``gbs-long`` and ``gbs-quad`` (``accuracy`` only): Gragg-Bulirsch-Stoer
extrapolation in the generated C in long double and ``_Float128`` (:mod:`..extended`)."""
from __future__ import annotations

__all__ = ["final_state"]


def final_state(model, param: list[float], y0: list[float], t_end: float, tol: float) -> tuple[list, int, int, str]:
    """One run of ``model`` (:class:`..extended.ExtendedModel`) from t = 0 to ``t_end`` at
    ``tol``: ``(y_end, evaluations, steps, status)``, ``y_end`` in the type's precision
    (status '' when it got there)."""
    r = model.integrate(param, y0, t_end, tol=tol)
    status = "" if r.status == 0 else f"extrapolation status {r.status}"
    return r.state, r.evaluations, r.steps, status
