"""``kronsub sweep MODEL``: many runs over a grid or a sample of parameters and initial values,
a row of summaries each, as a Parquet dataset with a JSON sidecar (:mod:`kronsub.sweep`)."""
from __future__ import annotations

import os
import platform
from pathlib import Path

import click

from ..simulation.methods import help_text as method_help
from ..version import __version__
from .common import (USAGE_ERROR, budget_option, check_times, fail, interrupted_by, note_safely, run_command, say,
                     scene_option, scene_system, separate_outputs, set_option, writable_outputs)

INSTALL_HINT = "pip install 'kronsub[sweep]'"


@click.command()
@click.argument("model", type=click.Path(dir_okay=False, path_type=Path))
@click.option("--grid", "grids", multiple=True, metavar="NAME=a:b:n",
              help="Sweep a parameter, coordinate or velocity over n values from a to b (repeatable; the grids are "
                   "crossed); log:a:b:n for a logarithmic grid, [v1, v2, ...] for a list.")
@click.option("--sample", "samples", multiple=True, metavar="NAME=DIST",
              help="Draw a parameter or initial value from uniform(a, b), normal(mu, sd) or loguniform(a, b), "
                   "--runs times (per grid point).")
@click.option("--runs", type=int, default=None, help="Draws of the --sample axes.")
@click.option("--seed", type=click.IntRange(min=0, max=2**63 - 1), default=0, show_default=True,
              help="Seed of the draws: the same spec and seed give the same runs, however they are split.")
@click.option("--latin", is_flag=True, help="Latin hypercube: one draw in each of --runs strata of every --sample axis.")
@click.option("--t", "t_end", type=float, default=None, help="End time (default: the scene's, else 10).")
@click.option("--dt", type=float, default=None,
              help="Output interval over which min and max are taken, and step of fixed-step methods "
                   "(default: the scene's, else 0.01).")
@click.option("--method", default=None, help="Default: the scene's, else dop853. " + method_help())
@click.option("--rtol", type=float, default=1e-10, show_default=True, help="Relative tolerance (adaptive methods).")
@click.option("--atol", type=float, default=1e-10, show_default=True, help="Absolute tolerance (adaptive methods).")
@click.option("--summary", "summaries", multiple=True, metavar="[NAME=]OUTPUT",
              help="A column of your own (repeatable): max, min, mean, initial or final of an expression of the "
                   "model's names and t, e.g. 'max(abs(theta))', or first_time of a comparison, e.g. "
                   "'flip=first_time(phi > pi)' (NaN when never).")
@click.option("--plot", type=click.Path(dir_okay=False, path_type=Path), default=None,
              help="A PNG heat map of one column (--plot-column) over a sweep's two --grid axes.")
@click.option("--plot-column", default=None, metavar="COLUMN",
              help="The column --plot maps (default: the last --summary, else the first final coordinate).")
@set_option("Set a parameter or initial value shared by every run (repeatable).")
@click.option("--output", "-o", type=click.Path(path_type=Path), required=True,
              help="The output folder: one Parquet part per chunk (a dataset), the metadata beside it as JSON "
                   "(runs.parquet -> runs.parquet.json).")
@click.option("--chunk", type=click.IntRange(min=1), default=None, help="Runs per task (default 1000).")
@click.option("--scheduler", default=None, metavar="ADDRESS",
              help="A running Dask scheduler, e.g. tcp://host:8786 (default: $DASK_SCHEDULER_ADDRESS, else a local "
                   "cluster on this machine's cores).")
@click.option("--workers", type=click.IntRange(min=1), default=None,
              help="Workers of the local cluster (default: one per core).")
@click.option("--resume", is_flag=True, help="Finish the sweep in --output: only the chunks not written yet.")
@click.option("--force", is_flag=True, help="Replace an existing --output.")
@scene_option
@budget_option
def sweep(model: Path, grids, samples, runs, seed, latin, t_end, dt, method, rtol, atol, summaries, plot, plot_column,
          settings, output, chunk, scheduler, workers, resume, force, scene_name):
    """Run MODEL over a grid or a sample of its parameters and initial values: a row per run
    (inputs, status, final state, min and max of each coordinate, energy drift, cost)."""
    def job():
        try:
            import distributed  # noqa: F401
            import pyarrow  # noqa: F401
        except ImportError:
            fail(f"Error: kronsub sweep needs dask.distributed and pyarrow\n  hint: {INSTALL_HINT}")
        from ..model.scenes import initial_values
        from ..simulation.values import parse_assignments
        from ..sweep.axes import read_axes
        from ..sweep.chunk import columns
        from ..sweep.dataset import Dataset, DatasetError
        from ..sweep.driver import ENV_SCHEDULER, SweepProgress, execute
        from ..sweep.study import DEFAULT_CHUNK, SweepError, make_job, make_plan

        check_times(t_end, dt)
        grid_axes, sample_axes = read_axes(grids, samples)
        try:
            plan = make_plan(grid_axes, sample_axes, runs, seed, latin)
        except SweepError as exc:
            fail(f"Error: {exc}", USAGE_ERROR)
        separate_outputs(model, ("--output", output, "output"), ("--plot", plot, "plot"))
        if plot is not None:
            if len(grid_axes) != 2 or sample_axes:
                fail("Error: --plot maps a sweep over exactly two --grid axes (and no --sample)\n"
                     "  hint: give two --grid NAME=a:b:n", USAGE_ERROR)
            writable_outputs(None, plot)
        if (output.exists() or Path(str(output) + ".json").exists()) and not (resume or force):
            fail(f"Error: {output} exists\n  hint: --resume finishes the sweep written there, --force replaces it, "
                 "or choose another -o")
        address = scheduler or os.environ.get(ENV_SCHEDULER) or None
        loaded, scene, system = scene_system(model, scene_name)
        pick = lambda given, scene_value, default: given if given is not None else (  # noqa: E731
            scene_value if scene_value is not None else default)
        span = pick(t_end, scene and scene.t_end, 10.0)
        step = pick(dt, scene and scene.dt, 0.01)
        chosen = pick(method, scene and scene.method, "dop853")
        assignments = parse_assignments(settings)
        where = {a.name: f"--grid {a.name}={a.text}" for a in grid_axes}
        where.update({a.name: f"--sample {a.name}={a.text}" for a in sample_axes})
        try:
            job_ = make_job(system, plan, initial_values(loaded, scene), assignments, method=chosen, t_end=span,
                            dt=step, rtol=rtol, atol=atol, outputs=scene.outputs if scene is not None else None,
                            chunk=chunk or DEFAULT_CHUNK, axes_text=where, summaries=summaries)
        except SweepError as exc:
            fail(f"Error: {exc}", USAGE_ERROR)
        identity = {"model": loaded.source.sha256 if loaded.source is not None else None,
                    "uses": [f.sha256 for f in loaded.uses], "scene": scene.name if scene is not None else None,
                    "spec": plan.describe(), "set": dict(sorted(assignments.items())), "method": chosen,
                    "rtol": rtol, "atol": atol, "t_end": span, "dt": step, "chunk": job_.chunk,
                    "summaries": {out.name: out.text for out in job_.summaries}}
        dataset = Dataset(output, columns(job_))
        mapped = None
        if plot is not None:
            mapped = plot_column or (job_.summaries[-1].name if job_.summaries else f"final_{system.coordinates[0].name}")
            if mapped not in {name for name, kind in dataset.columns if kind == "float64"} or mapped in plan.names:
                fail(f"Error: --plot-column {mapped}: no numeric output column of that name\n  hint: choose one of "
                     + ", ".join(n for n, k in dataset.columns if k == "float64" and n not in plan.names), USAGE_ERROR)
        try:
            written = dataset.prepare(identity, resume=resume, force=force)
        except DatasetError as exc:
            fail(f"Error: {exc}")
        todo = [i for i in range(job_.chunks) if i not in written]

        def sidecar(state: str, chunks_written: int, counts=None):
            from ..simulation.table import model_record

            import dask
            import pyarrow

            dataset.write_sidecar({
                "identity": identity, "state": state, "route": job_.route,
                "model": model_record(system.name, model.as_posix(), loaded.source, loaded.uses),
                "runs": plan.count, "chunks": job_.chunks, "chunks_written": chunks_written,
                "counts": counts if counts is not None else dataset.counts(),
                "columns": [name for name, _ in dataset.columns],
                "library_sha256": job_.sources.sha256 if job_.sources is not None else None,
                "versions": {"kronsub": __version__, "dask": dask.__version__, "pyarrow": pyarrow.__version__,
                             "python": platform.python_version()}})

        sidecar("running", len(written), {})
        finished = [len(written)]

        def done(index, rows):
            dataset.write(index, rows)
            finished[0] += 1

        if written:
            say(f"note: {len(written)} of {job_.chunks} chunks already written in {output}; computing "
                f"{len(todo)}")
        try:
            execute(job_, todo, done, scheduler=address, workers=workers,
                    progress=SweepProgress(sum(min(job_.chunk, plan.count - i * job_.chunk) for i in todo)))
        except KeyboardInterrupt as exc:
            from ..interrupts import exit_code, signal_of

            sidecar("interrupted", finished[0])
            fail(f"Interrupted{interrupted_by(signal_of(exc))}: {finished[0]} of {job_.chunks} chunks kept in "
                 f"{output}\n  hint: --resume finishes it", exit_code(exc))
        counts = dataset.counts()
        sidecar("complete", finished[0], counts)
        if plot is not None:
            from ..sweep.plot import heat_map

            heat_map(dataset.folder, plan, mapped, system, plot)
            say(f"wrote {plot}")
        note_safely(f"wrote {output} ({plan.count:,} runs: "
                    + ", ".join(f"{n:,} {status}" for status, n in counts.items()) + f"; metadata {dataset.sidecar})")

    run_command(job)
