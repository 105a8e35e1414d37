"""Advice after a run: a stiff problem (Hairer's test, or the step size held on the stability
boundary) and a conservative model whose energy ``E = T + V`` (24) was not kept."""
from __future__ import annotations

import numpy as np



__all__ = ["ENERGY_DRIFT_SHARE", "ENERGY_FLOOR_SHARE", "EnergyWarning", "MODE_SHARE", "STIFF_DAMPED_SHARE",
           "STIFF_MIN_STEPS", "STIFF_REJECTED_SHARE", "StiffnessWarning", "conserves_energy", "energy_advice",
           "is_stiff", "mode_coordinates", "stiffness_advice"]


class StiffnessWarning(UserWarning):
    """An explicit method found the problem stiff (Hairer's test): an implicit one would be cheaper."""


class EnergyWarning(UserWarning):
    """A run did not keep the energy of a model that conserves it: its rows are not accurate."""


ENERGY_DRIFT_SHARE = 1e-2  # of the largest kinetic energy: no run accurate to any tolerance drifts this far


ENERGY_FLOOR_SHARE = 1e-6  # of |E|: the scale of a run that hardly moves (the rounding of V is not a drift)


def energy_advice(native, param, nq: int, method: str, t0: float, y0, E0: float, T_max: float, E1: float) -> str:
    """A warning when the energy changed by more than ``ENERGY_DRIFT_SHARE`` of its scale over a
    run of a model that conserves it (else ""): a run that went wrong without failing, such as
    heyoka's step fooled by a Taylor series with gaps (a motion from rest at a symmetric
    position, benchmarks/HISTORY.md). The scale is the energy the motion exchanges, its largest
    kinetic energy, not ``|E|``, which an offset of the potential can make as large as it likes;
    ``ENERGY_FLOOR_SHARE |E|`` below it."""
    scale = max(T_max, ENERGY_FLOOR_SHARE * abs(E0))
    if not (np.isfinite(E1) and scale > 0) or abs(E1 - E0) <= ENERGY_DRIFT_SHARE * scale:
        return ""
    try:
        if not conserves_energy(native, param, nq, t0, y0):
            return ""
    except Exception:  # noqa: BLE001 - the check is a courtesy; a failed evaluation must not stop the run
        return ""
    hint = ("heyoka reads its step size off its last two Taylor orders, which a motion from rest at a symmetric "
            "position can fool: use --method taylor or dop853" if method == "heyoka" else
            "tighten --rtol (adaptive methods) or --dt (fixed-step methods), or try another --method")
    return (f"the energy of this conservative model went from {E0:.6g} to {E1:.6g} over the run, "
            f"{abs(E1 - E0) / scale:.2g} of its largest kinetic energy ({scale:.3g}): "
            f"{method}'s rows are not accurate; {hint}")


def conserves_energy(native, param, nq: int, t0: float, y0) -> bool:
    """Whether ``dE/dt = 0`` along the equations (``E = T + V``, ``V`` of the conservative
    effects): at three states with random velocities (or speeds: ``y0`` is ``[q; u]`` in the
    speeds) about the first row, the rate,
    by central differences, is below 1e-6 of the sum of its terms' magnitudes. Damping, driving,
    loads or connections that depend on time all give a rate of the order of its terms."""
    rng = np.random.default_rng(20261124)
    y0 = np.asarray(y0, dtype=float)

    def energy(t, y):
        return native.kinetic_energy(y, param) + native.potential_energy(t, y, param)

    for _ in range(3):
        y = y0.copy()
        y[nq:] += rng.standard_normal(len(y) - nq) * max(1.0, float(np.max(np.abs(y0[nq:]), initial=0.0)))
        ydot = native.rhs(t0, y, param)
        dt = 1e-5 * max(1.0, abs(t0))
        terms = [(energy(t0 + dt, y) - energy(t0 - dt, y)) / (2 * dt)]
        for i in range(len(y)):
            e = np.zeros_like(y)
            e[i] = 1e-5 * max(1.0, abs(y[i]))
            terms.append((energy(t0, y + e) - energy(t0, y - e)) / (2 * e[i]) * ydot[i])
        if not abs(sum(terms)) <= 1e-6 * sum(map(abs, terms)):
            return False
    return True


def is_stiff(stats: dict) -> bool:
    """Whether an explicit adaptive run's step size was held by stability: Hairer's test fired, or
    the step size bounced on the stability boundary (a large share of rejected steps over many)."""
    steps, rejected = stats.get("steps", 0), stats.get("rejected", 0)
    return "stiff_from" in stats or (steps + rejected >= STIFF_MIN_STEPS
                                     and rejected >= STIFF_REJECTED_SHARE * (steps + rejected))


def _fastest_mode(native, param, t: float, y: np.ndarray) -> tuple[complex, np.ndarray]:
    """The eigenvalue of largest modulus of the Jacobian of the right-hand side at ``y``
    (central differences), and its eigenvector."""
    n = len(y)
    J = np.empty((n, n))
    for j in range(n):
        e = np.zeros(n)
        e[j] = 1e-6 * max(1.0, abs(y[j]))
        J[:, j] = (native.rhs(t, y + e, param) - native.rhs(t, y - e, param)) / (2 * e[j])
    lam, vectors = np.linalg.eig(J)
    k = int(np.argmax(np.abs(lam)))
    return complex(lam[k]), vectors[:, k]


MODE_SHARE = 0.3
"""A coordinate whose share of the fastest mode is at least this of the largest share is named."""


def mode_coordinates(lam: complex, vector: np.ndarray, names) -> list[str]:
    """The coordinates that carry a mode ``(lam, vector)`` of ``y = [q; qdot]``: the share of
    coordinate ``i`` is ``max(|lam v_i|, |v_(n+i)|)`` (its rate in the mode, so that positions
    and velocities compare; a first-order coordinate's velocity slot is not integrated)."""
    n = len(names)
    if n == 0 or len(vector) != 2 * n:
        return []
    share = np.maximum(abs(lam) * np.abs(vector[:n]), np.abs(vector[n:]))
    top = float(np.max(share))
    return [name for name, s in zip(names, share) if top > 0 and s >= MODE_SHARE * top]


def _describe_mode(lam: complex, vector, names, charges) -> str:
    carried = mode_coordinates(lam, vector, names) if vector is not None else []
    if not carried:
        return ""
    kind = ""
    if charges and all(name in charges for name in carried):
        kind = "an electrical mode, the currents of "
    elif charges and any(name in charges for name in carried):
        kind = "an electromechanical mode of "
    time = f", time constant {1 / abs(lam.real):.3g}" if np.isfinite(lam.real) and lam.real < 0 else ""
    return f"; it is {kind}{', '.join(carried)}{time}"


def stiffness_advice(native, param, stats: dict, span: float, t: float, y, method: str, names=(),
                     charges=frozenset()) -> str:
    """What to do about a stiff run: an implicit method when its fastest mode (at the last state
    ``y`` at time ``t``) is damped; when it is an undamped oscillation, every method has to
    follow it, so say that instead. ``names`` (the coordinates) and ``charges`` (those that move
    a circuit's branch charge) name what the mode moves: an electrical mode is the currents of
    the loops, its time constant ``1/|Re lambda|`` (``L/R`` of a loop)."""
    steps, rejected = stats["steps"], stats["rejected"]
    cost = f"{steps} steps, {rejected} rejected, mean step {span / max(steps, 1):.3g}"
    try:
        lam, vector = _fastest_mode(native, param, t, np.asarray(y, dtype=float))
    except Exception:  # noqa: BLE001 - the advice is a courtesy; a failed evaluation must not stop the run
        lam, vector = complex("nan"), None
    mode = f"fastest mode lambda = {lam.real:.3g}{lam.imag:+.3g}i" + _describe_mode(lam, vector, list(names), charges)
    if np.isfinite(lam.real) and -lam.real >= STIFF_DAMPED_SHARE * abs(lam):
        return (f"the problem is stiff: {method}'s step size is held by stability, not accuracy ({cost}; {mode}); "
                "an implicit method is far cheaper here: use --method Radau"
                + (" (with --jacobian exact)" if method != "Radau" else ""))
    return (f"a fast oscillation holds {method}'s step size ({cost}; {mode}, period "
            f"{2 * np.pi / max(abs(lam.imag), 1e-300):.3g}): it is undamped, so every method must follow it; "
            "an implicit method (--method Radau) pays off only where the fast mode is damped")


STIFF_MIN_STEPS = 5000        # fewer steps are cheap whatever the cause


STIFF_REJECTED_SHARE = 0.25   # accuracy-limited smooth runs reject a few per cent


STIFF_DAMPED_SHARE = 0.05     # a fast mode that decays by e within 20 radians counts as damped
