"""The reports of a work-precision measurement (:mod:`.accuracy`): a Markdown table with the
cheapest point meeting a target, a plain CSV of the points, its JSON metadata, and a plot."""
from __future__ import annotations

import dataclasses
import math

import mpmath

from ..emitters.escape import markdown_text, plot_text
from ..interrupts import signal_name
from ..model.file_reading import SourceFile
from .accuracy import REFERENCE_MARGIN, WorkPrecision
from .plot import plot_format

__all__ = ["CSV_COLUMNS", "METADATA_FORMAT", "markdown", "metadata", "plot", "target_sentence", "work_precision_csv"]


def _number(value, fmt: str) -> str:
    return "" if value is None or (isinstance(value, float) and math.isnan(value)) else format(value, fmt)


def markdown(wp: WorkPrecision, target: float | None = None) -> str:
    """The table, the reference and the cheapest point meeting ``target``."""
    ref = wp.reference
    lines = [f"# Work-precision: {markdown_text(wp.system)}, t = 0 .. {wp.t_end:g}", "",
             f"Reference at t = {', '.join(f'{t:g}' for t in ref.times)}: {ref.routes[0]}; estimated "
             f"error {ref.error:.1e} ({'; '.join(ref.routes[1:])}).", ""]
    if wp.compile_seconds is not None:
        lines += [f"Compiling the C right-hand side and integrators: {wp.compile_seconds:.2f} s (apart from "
                  "the times below; cached after the first run).", ""]
    loop = bool(wp.constraints)
    extra_head = " max \\|g\\| | max \\|G ydot\\| |" if loop else ""
    lines += ["| method | setting | error at t_end | energy drift |" + extra_head + " time [ms] | f evals | steps | note |",
              "|---|---|---:|---:|" + ("---:|---:|" if loop else "") + "---:|---:|---:|---|"]
    for p in wp.points:
        if not p.ok:  # nothing of a failed run is a measurement: the status says what happened
            blank = " |" * (2 if loop else 0)
            lines.append(f"| {p.method} | {p.setting} | failed | |{blank} | | | "
                         f"{markdown_text(p.status or 'a non-finite state')} |")
            continue
        note = markdown_text(p.status) or (f"compile {p.compile_seconds:.2f} s" if p.compile_seconds is not None else "")
        extra = f" {_number(p.constraint_residual, '.1e')} | {_number(p.velocity_residual, '.1e')} |" if loop else ""
        lines.append(f"| {p.method} | {p.setting} | {_number(p.error, '.2e')} | {_number(p.energy_drift, '.1e')} |"
                     f"{extra} {1e3 * p.seconds:.3f} | {_number(p.evaluations, 'd')} | {_number(p.steps, 'd')} | {note} |")
    lines.append("")
    state = ("[q; qdot] of the independent coordinates" if loop else
             "[q; u] (the speeds u: " + ", ".join(markdown_text(u) for u in wp.speeds) + ")" if wp.speeds else "[q; qdot]")
    lines.append(f"Error: max over the state {state} at t_end; time: median of repeated integrations; "
                 + ("energy drift: |E(t_end) - E(0)| / |E| (the model conserves energy)."
                    if wp.conservative else "energy drift: not reported (the model does not conserve energy)."))
    if loop:
        lines.append(f"Closed loop ({', '.join(wp.constraints)}): max |g| and max |G ydot| are the largest residuals "
                     "of the constraints and of their velocity form over the run's steps, the dependent coordinates "
                     "found as the run finds them (Newton's method to min(rtol, atol)/100, within 1e-14 .. 1e-8).")
    for method, why in wp.skipped.items():
        lines.append(f"- {method}: skipped, {markdown_text(why)}")
    if target is not None:
        lines.append("")
        lines.append(target_sentence(wp, target))
    return "\n".join(lines) + "\n"


def target_sentence(wp: WorkPrecision, target: float) -> str:
    """The cheapest point meeting ``target`` at its tolerance and every tighter one, and the quicker
    point that met it only by the scatter of the error, if any."""
    best, chance = wp.cheapest(target), wp.by_chance(target)
    luck = "" if chance is None else (
        f" {chance.method} at {chance.setting} met it in {1e3 * chance.seconds:.3f} ms (error {chance.error:.1e}), "
        f"but a tighter tolerance of {chance.method} did not: the error scatters there, so that was chance.")
    if best is None:
        closest = wp.best_error()
        return (f"Target {target:.2g}: no method met it at a tolerance and every tighter one" +
                (f" (best error {closest:.1e})." if closest is not None else ".") + luck)
    return (f"Target {target:.2g}: cheapest is {best.method} at {best.setting}: error {best.error:.1e} "
            f"in {1e3 * best.seconds:.3f} ms, and at every tighter tolerance {best.method} ran at." + luck)


CSV_COLUMNS = ("method", "tolerance", "setting", "error", "energy_drift", "constraint_residual",
               "velocity_residual", "seconds", "compile_seconds", "evaluations", "steps", "repeats", "status")
METADATA_FORMAT = "kronsub-accuracy-metadata/1"


def work_precision_csv(wp: WorkPrecision) -> str:
    """One header row (:data:`CSV_COLUMNS`), then one row per point: plain CSV that
    ``numpy.genfromtxt``, ``csv.DictReader`` and ``pandas.read_csv`` read without options.
    Numbers in their shortest round-trip form, ``nan`` where a value does not apply (no energy
    drift for a model that does not conserve energy, no residuals without constraints, no
    evaluation count from a method that does not report it); ``status`` is ``ok`` or ``failed``
    (the message is in the metadata, :func:`metadata`); a failed point has no error, energy
    drift or residual (``nan``)."""
    def number(value) -> str:
        return "nan" if value is None else repr(float(value)) if not isinstance(value, int) else str(value)

    lines = [",".join(CSV_COLUMNS)]
    for p in wp.points:
        if not p.ok:  # the cost until it failed is kept; no error or drift was measured
            p = dataclasses.replace(p, error=None, energy_drift=None, constraint_residual=None,
                                    velocity_residual=None)
        lines.append(",".join([p.method, repr(p.tolerance), p.setting, number(p.error), number(p.energy_drift),
                               number(p.constraint_residual), number(p.velocity_residual), number(p.seconds),
                               number(p.compile_seconds), number(p.evaluations), number(p.steps), str(p.repeats),
                               "ok" if p.ok else "failed"]))
    return "\n".join(lines) + "\n"


def metadata(wp: WorkPrecision, *, model_file: str | None = None, source: SourceFile | None = None,
             uses: tuple[SourceFile, ...] = (), scene: str | None = None, methods: tuple[str, ...] = (), tolerances: tuple[float, ...] = (),
             target: float | None = None, csv: str | None = None) -> dict:
    """Everything about a measurement that is not a point: the model, the reference (its routes,
    estimated error and state at the end time, 30 digits), what was skipped and why, the
    failures' messages, the target's choice. Written as JSON beside the CSV."""
    from ..version import __version__
    from .table import json_number, model_record

    ref = wp.reference
    names = list(wp.initial_state) or [f"y{i}" for i in range(len(ref.states[-1]))]
    with mpmath.workdps(max(ref.digits, 30) + 5):
        end_state = {name: mpmath.nstr(v, 30, strip_zeros=False) for name, v in zip(names, ref.states[-1])}
    meta = {
        "format": METADATA_FORMAT,
        "kronsub": __version__,
        "csv": csv,
        "model": model_record(wp.system, model_file, source, uses),
        "scene": scene,
        "t_end": json_number(wp.t_end),
        "parameters": {k: json_number(v) for k, v in wp.parameters.items()},
        "initial_state": {k: json_number(v) for k, v in wp.initial_state.items()},
    }
    if wp.constraints:
        meta["closed_loop"] = {"constraints": list(wp.constraints),
                               "dependent_at_t0": {k: json_number(v) for k, v in wp.dependent.items()},
                               "state": "the independent coordinates and their velocities"}
    best = wp.best_error()
    meta.update({
        "methods": list(methods),
        "tolerances": [json_number(t) for t in tolerances],
        "reference": {
            "times": [json_number(t) for t in ref.times],
            "route": ref.routes[0],
            "cross_checks": list(ref.routes[1:]),
            "estimated_error": json_number(ref.error),
            "digits": ref.digits,
            "state_at_t_end": end_state,
            "sufficient": wp.reference_sufficient(),
            "required_margin": REFERENCE_MARGIN,
            "best_point_error": json_number(best),
        },
        "compile_seconds": json_number(wp.compile_seconds),
        "conservative": wp.conservative,
        "status": "complete" if wp.interrupted is None else "interrupted",
        "interrupted_by": None if wp.interrupted is None else signal_name(wp.interrupted),
        "skipped": dict(wp.skipped),
        "failures": [{"method": p.method, "setting": p.setting, "message": p.status or "non-finite state"}
                     for p in wp.points if not p.ok],
        "columns": list(CSV_COLUMNS),
        "units": ("error and residuals in the state's units (max over its entries); energy_drift relative to the "
                  "largest |E| or T; seconds: median wall time of repeated integrations, compile_seconds apart"),
    })
    if target is not None:
        def point(p):
            return None if p is None else {"method": p.method, "setting": p.setting, "error": json_number(p.error),
                                           "seconds": json_number(p.seconds)}
        meta["target"] = {"error": json_number(target), "cheapest": point(wp.cheapest(target)),
                          "by_chance": point(wp.by_chance(target))}
    return meta


def plot(wp: WorkPrecision, path, target: float | None = None) -> None:
    """Error against time, log-log, one line per method (matplotlib); written atomically."""
    from pathlib import Path

    import matplotlib

    from ..atomic import atomic_file

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(8, 5.5))
    for method in dict.fromkeys(p.method for p in wp.points):
        pts = [p for p in wp.points if p.method == method and p.ok and p.error > 0]
        if pts:
            ax.loglog([1e3 * p.seconds for p in pts], [p.error for p in pts], "o-", label=method)
    ax.axhline(wp.reference.error, color="grey", linestyle=":", label="reference error")
    if target is not None:
        ax.axhline(target, color="red", linestyle="--", label=f"target {target:.2g}")
    ax.set_xlabel("integration time [ms]")
    ax.set_ylabel(f"max |error| at t = {wp.t_end:g}")
    ax.set_title(f"Work-precision: {plot_text(wp.system)}")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize="small")
    fig.tight_layout()
    try:
        with atomic_file(Path(path), binary=True) as fh:  # the user's umask, no stray temporary file
            fig.savefig(fh, dpi=100, format=plot_format(path) or "png")  # a FIFO or a device: PNG
    finally:
        plt.close(fig)
