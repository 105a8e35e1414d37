"""``kronsub sweep MODEL``: many runs over a grid or a sample of parameters and initial values,
a row of summaries each, as a Parquet dataset with a JSON sidecar (:mod:`kronsub.sweep`)."""
from __future__ import annotations

import dataclasses
import os
import platform
from pathlib import Path

import click

from ..errors import ModelError
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
@click.option("--table", "tables", multiple=True, metavar="FILE",
              help="A table of runs, CSV (a header row of names, then numbers) or Parquet: a run per row, its "
                   "columns parameters and initial values (crossed with --grid axes).")
@click.option("--runs", type=int, default=None, help="Draws of the --sample axes.")
@click.option("--seed", type=click.IntRange(min=0, max=2**63 - 1), default=None,
              help="Seed of the draws (default 0): the same spec and seed give the same runs, however they are split.")
@click.option("--latin", is_flag=True, help="Latin hypercube: one draw in each of --runs strata of every --sample axis.")
@click.option("--t", "t_end", type=float, default=None, help="End time (default: the scene's, else 10).")
@click.option("--dt", type=float, default=None,
              help="Output interval over which min and max are taken, and step of fixed-step methods "
                   "(default: the scene's, else 0.01).")
@click.option("--method", default=None, help="Default: the scene's, else dop853. " + method_help())
@click.option("--rtol", type=float, default=None, help="Relative tolerance (adaptive methods; default 1e-10).")
@click.option("--atol", type=float, default=None, help="Absolute tolerance (adaptive methods; default 1e-10).")
@click.option("--summary", "summaries", multiple=True, metavar="[NAME=]OUTPUT",
              help="A column of your own (repeatable): max, min, mean, initial or final of an expression of the "
                   "model's names and t, e.g. 'max(abs(theta))', or first_time of a comparison, e.g. "
                   "'flip=first_time(phi > pi)' (NaN when never).")
@click.option("--plot", type=click.Path(dir_okay=False, path_type=Path), default=None,
              help="A PNG heat map of one column (--plot-column) over a sweep's two --grid axes.")
@click.option("--plot-column", default=None, metavar="COLUMN",
              help="The column --plot maps (default: the last --summary, else the first final coordinate).")
@set_option("Set a parameter or initial value shared by every run (repeatable).")
@click.option("--output", "-o", type=click.Path(path_type=Path), default=None,
              help="The output folder: one Parquet part per chunk (a dataset), the metadata beside it as JSON "
                   "(runs.parquet -> runs.parquet.json).")
@click.option("--trajectories", type=click.Path(path_type=Path), default=None, metavar="DIR",
              help="Also keep every run's rows at --dt (t, coordinates and velocities, as `kronsub simulate` "
                   "writes them, after a run column): a Parquet dataset of one part per chunk in DIR, written by "
                   "the workers (on a cluster, a folder they share with this machine at the same path).")
@click.option("--chunk", type=click.IntRange(min=1), default=None, help="Runs per task (default 1000).")
@click.option("--scheduler", default=None, metavar="ADDRESS",
              help="A running Dask scheduler, e.g. tcp://host:8786 (default: $DASK_SCHEDULER_ADDRESS, else a local "
                   "cluster on this machine's cores).")
@click.option("--workers", type=click.IntRange(min=1), default=None,
              help="Workers of the local cluster (default: one per core).")
@click.option("--resume", is_flag=True, help="Finish the sweep in --output (and --trajectories): only the chunks not written yet.")
@click.option("--force", is_flag=True, help="Replace an existing --output (and --trajectories).")
@scene_option
@budget_option
def sweep(model: Path, grids, samples, tables, runs, seed, latin, t_end, dt, method, rtol, atol, summaries, plot, plot_column,
          settings, output, trajectories, chunk, scheduler, workers, resume, force, scene_name):
    """Run MODEL over a grid or a sample of its parameters and initial values: a row per run
    (inputs, status, final state, min and max of each coordinate, energy drift, cost). MODEL
    may be a sweep file (STUDY.yaml, with `sweep:` at its top), whose values the options
    override or add to."""
    def job():
        nonlocal model, grids, samples, runs, seed, latin, t_end, dt, method, rtol, atol, summaries, settings, output
        nonlocal chunk, scene_name, tables, trajectories
        try:
            import distributed  # noqa: F401
            import pyarrow  # noqa: F401
        except ImportError:
            fail(f"Error: kronsub sweep needs dask.distributed and pyarrow\n  hint: {INSTALL_HINT}")
        from ..model.scenes import initial_values
        from ..simulation.values import parse_assignments
        from ..sweep.axes import read_axes
        from ..sweep.chunk import columns
        from ..sweep.dataset import Dataset, DatasetError, part_name
        from ..sweep.driver import ENV_SCHEDULER, SweepProgress, execute
        from ..sweep.study import DEFAULT_CHUNK, SweepError, make_job, make_plan

        from ..sweep.study_file import is_study, read_study

        located: dict[str, object] = {}  # an option's text -> where the sweep file wrote it
        study_file = None
        if is_study(model):
            study_file = model
            study = read_study(model)
            v = study.values
            model = v["model"]
            study_grids = tuple(f"{k}={t}" for k, t in v.get("grid", {}).items())
            study_samples = tuple(f"{k}={t}" for k, t in v.get("sample", {}).items())
            study_summaries = tuple(f"{k}={t}" for k, t in v.get("summaries", {}).items())
            tables = ((str(v["table"]),) if "table" in v else ()) + tables
            for option, key, items in (("--grid", "grid", study_grids), ("--sample", "sample", study_samples),
                                       ("--summary", "summaries", study_summaries)):
                for item in items:
                    located[f"{option} {item}"] = study.where[(key, item.partition("=")[0])]
            grids, samples, summaries = study_grids + grids, study_samples + samples, study_summaries + summaries
            settings = tuple(f"{k}={t}" for k, t in v.get("set", {}).items() if not any(
                s.partition("=")[0].strip() == k for s in settings)) + settings
            runs = runs if runs is not None else v.get("runs")
            seed = seed if seed is not None else v.get("seed")
            latin = latin or v.get("latin", False)
            t_end = t_end if t_end is not None else v.get("t")
            dt = dt if dt is not None else v.get("dt")
            method = method if method is not None else v.get("method")
            rtol = rtol if rtol is not None else v.get("rtol")
            atol = atol if atol is not None else v.get("atol")
            chunk = chunk if chunk is not None else v.get("chunk")
            output = output if output is not None else v.get("output")
            trajectories = trajectories if trajectories is not None else v.get("trajectories")
            scene_name = scene_name if scene_name is not None else v.get("scene")
        rtol = 1e-10 if rtol is None else rtol
        atol = 1e-10 if atol is None else atol
        seed = 0 if seed is None else seed
        if output is None:
            fail("Error: no output folder\n  hint: give -o runs.parquet (or output: in the sweep file)", USAGE_ERROR)
        check_times(t_end, dt)
        try:
            grid_axes, sample_axes = read_axes(grids, samples, tables)
        except ModelError as exc:
            raise relocated(exc, located) from None
        try:
            plan = make_plan(grid_axes, sample_axes, runs, seed, latin)
        except SweepError as exc:
            fail(f"Error: {exc}", USAGE_ERROR)
        from ..simulation.table import sidecar_path

        metadata = lambda folder, option: (  # noqa: E731
            f"{option} {folder}: its metadata", folder and sidecar_path(folder), f"{option} metadata", option)
        separate_outputs(model, ("--output", output, "output"), metadata(output, "-o"), ("--plot", plot, "plot"),
                         ("--trajectories", trajectories, "trajectories"), metadata(trajectories, "--trajectories"),
                         inputs=tuple(("--table", Path(t), "--table") for t in tables)
                         + ((("STUDY", study_file, "sweep"),) if study_file is not None else ()))
        if trajectories is not None and nested(trajectories, output):
            fail(f"Error: --trajectories {trajectories} and the output {output} are one inside the other\n"
                 "  hint: give them separate folders, e.g. -o runs.parquet --trajectories rows.parquet", USAGE_ERROR)
        if plot is not None:
            if len(grid_axes) != 2 or sample_axes or any(not hasattr(a, "at") for a in grid_axes):
                fail("Error: --plot maps a sweep over exactly two --grid axes (and no --sample)\n"
                     "  hint: give two --grid NAME=a:b:n", USAGE_ERROR)
            writable_outputs(None, plot)
        for given, option in ((output, "-o"), (trajectories, "--trajectories")):
            if given is not None and given.exists() and not given.is_dir():
                fail(f"Error: {given} exists and is not a folder\n  hint: a sweep writes a folder of Parquet parts; "
                     f"choose another {option}")
        if (output.exists() or Path(str(output) + ".json").exists()) and not (resume or force):
            fail(f"Error: {output} exists\n  hint: --resume finishes the sweep written there, --force replaces it, "
                 "or choose another -o")
        if trajectories is not None and (trajectories.exists() or Path(str(trajectories) + ".json").exists()) \
                and not (resume or force):
            fail(f"Error: {trajectories} exists\n  hint: --resume finishes the sweep written there, --force "
                 "replaces it, or choose another --trajectories")
        address = scheduler or os.environ.get(ENV_SCHEDULER) or None
        loaded, scene, system = scene_system(model, scene_name)
        pick = lambda given, scene_value, default: given if given is not None else (  # noqa: E731
            scene_value if scene_value is not None else default)
        span = pick(t_end, scene and scene.t_end, 10.0)
        step = pick(dt, scene and scene.dt, 0.01)
        chosen = pick(method, scene and scene.method, "dop853")
        assignments = parse_assignments(settings)
        where = {name: (f"--table {a.text}: column {name}" if hasattr(a, "sha256") else f"--grid {a.name}={a.text}")
                 for a in grid_axes for name in a.names}
        where.update({a.name: f"--sample {a.name}={a.text}" for a in sample_axes})
        kept = None
        if trajectories is not None:  # (before the C is emitted: a name the rows cannot hold is refused first)
            from ..sweep.trajectories import trajectory_columns

            kept = Dataset(trajectories, trajectory_columns(system, scene.outputs if scene is not None else None),
                           option="--trajectories")
        try:
            job_ = make_job(system, plan, initial_values(loaded, scene), assignments, method=chosen, t_end=span,
                            dt=step, rtol=rtol, atol=atol, outputs=scene.outputs if scene is not None else None,
                            chunk=chunk or DEFAULT_CHUNK, axes_text=where, summaries=summaries)
        except SweepError as exc:
            fail(f"Error: {exc}", USAGE_ERROR)
        except ModelError as exc:
            raise relocated(exc, located) from None
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
            if kept is not None:
                written &= kept.prepare(identity, resume=resume, force=force)  # a chunk is done with both parts
                job_ = dataclasses.replace(job_, trajectories=str(kept.folder.resolve()))
        except DatasetError as exc:
            fail(f"Error: {exc}")
        todo = [i for i in range(job_.chunks) if i not in written]

        def sidecar(state: str, chunks_written: int, counts=None):
            from ..simulation.table import model_record

            import dask
            import pyarrow as arrow

            if kept is not None:
                kept.write_sidecar({
                    "identity": identity, "state": state, "summaries": str(output), "runs": plan.count,
                    "chunks": job_.chunks, "chunks_written": chunks_written,
                    "columns": [name for name, _ in kept.columns],
                    "units": "t in s; coordinates and velocities in the model's units (per s)"})
            dataset.write_sidecar({
                "trajectories": str(trajectories) if trajectories is not None else None,
                "identity": identity, "state": state, "route": job_.route,
                "model": model_record(system.name, model.as_posix(), loaded.source, loaded.uses),
                "runs": plan.count, "chunks": job_.chunks, "chunks_written": chunks_written,
                "counts": counts if counts is not None else dataset.counts(),
                "columns": [name for name, _ in dataset.columns],
                "library_sha256": job_.sources.sha256 if job_.sources is not None else None,
                "versions": {"kronsub": __version__, "dask": dask.__version__, "pyarrow": arrow.__version__,
                             "python": platform.python_version()}})

        sidecar("running", len(written), {})
        finished = [len(written)]
        tally: dict[str, int] = {}

        def done(index, rows):
            if kept is not None and not (kept.folder / part_name(index)).exists():
                raise DatasetError(f"the workers wrote chunk {index}'s trajectories where this machine does not see "
                                   f"them ({kept.folder})\n  hint: on a cluster, --trajectories must be a folder the "
                                   "workers share with this machine, at the same path")
            dataset.write(index, rows)
            for status in rows["status"]:  # the new parts' counts, without reading them back
                tally[status] = tally.get(status, 0) + 1
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
        counts = dataset.counts(written, tally)
        sidecar("complete", finished[0], counts)
        if plot is not None:
            from ..sweep.plot import heat_map

            heat_map(dataset.folder, plan, mapped, system, plot)
            say(f"wrote {plot}")
        note_safely(f"wrote {output} ({plan.count:,} runs: "
                    + ", ".join(f"{n:,} {status}" for status, n in counts.items()) + f"; metadata {dataset.sidecar})")

    run_command(job)


def nested(a: Path, b: Path) -> bool:
    """Whether the folders ``a`` and ``b`` are one, or one holds the other."""
    a, b = a.resolve(), b.resolve()
    return a == b or a in b.parents or b in a.parents


def relocated(exc, located: dict):
    """``exc`` with the problems of values a sweep file wrote placed at their line and column."""
    import dataclasses

    from ..errors import ModelError

    problems = []
    for problem in exc.problems:
        where = located.get(str(problem.location)) if problem.location is not None else None
        if where is None and problem.location is not None:  # the axis named by make_job: its name only
            where = next((at for text, at in located.items() if text.split("=")[0] == str(problem.location).split("=")[0]
                          and str(problem.location).startswith(text.split("=")[0] + "=")), None)
        problems.append(dataclasses.replace(problem, location=where) if where is not None else problem)
    return ModelError(problems)
