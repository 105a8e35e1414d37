"""Sweeps from a notebook: :func:`sweep`, the rows ``kronsub sweep`` writes, as a DataFrame."""
from __future__ import annotations

import os
from typing import Mapping, Sequence

from ..core.known_system import KnownSystem
from .runs import settings_text

__all__ = ["sweep"]


def sweep(system: KnownSystem, grid: Mapping[str, object] | None = None, sample: Mapping[str, str] | None = None,
          runs: int | None = None, seed: int = 0, t: float = 10.0, dt: float = 0.01, method: str = "dop853",
          set: Mapping[str, object] | None = None, rtol: float = 1e-10, atol: float = 1e-10, *,
          latin: bool = False, scheduler: str | None = None, workers: int | None = None, chunk: int | None = None,
          summaries: Sequence[str] = (), trajectories: str | os.PathLike | None = None,
          output: str | os.PathLike | None = None, force: bool = False):
    """Many runs over a grid (``grid``: name -> ``"a:b:n"``, ``"log:a:b:n"`` or a list of values)
    and a sample (``sample``: name -> ``"uniform(a, b)"``, ``"normal(mu, sd)"``,
    ``"loguniform(a, b)"``, ``runs`` draws) of parameters and initial values, on Dask
    (``scheduler``, else a local cluster of ``workers``): a pandas DataFrame of a row per run,
    as the rows ``kronsub sweep`` writes (:mod:`kronsub.sweep`); ``summaries``: columns of your own
    (``"max(abs(theta))"``, ``"flip=first_time(phi > pi)"``, as ``--summary``); ``trajectories``: a
    folder the workers write every run's rows in (a Parquet dataset, as ``--trajectories``; an
    existing one is refused unless ``force``). The DataFrame holds every summary row in memory;
    with ``output`` (a folder, as ``-o``: for sweeps larger than memory) the rows go to a Parquet
    dataset a chunk at a time, with its JSON sidecar, and its path is returned instead."""
    import dataclasses
    from pathlib import Path

    import pandas

    from ..simulation.start import starting_values
    from ..sweep.axes import read_axes
    from ..sweep.driver import ENV_SCHEDULER, execute
    from ..sweep.study import DEFAULT_CHUNK, make_job, make_plan

    grids = tuple(f"{name}={spec}" if isinstance(spec, str) else
                  f"{name}=[{', '.join(repr(float(v)) for v in spec)}]" for name, spec in (grid or {}).items())
    samples = tuple(f"{name}={spec}" for name, spec in (sample or {}).items())
    plan = make_plan(*read_axes(grids, samples), runs, seed, latin)
    values = starting_values(system, settings_text(set)).values  # checks the fixed values
    settings = {p.name: repr(v) for p, v in zip(system.parameters, values.parameters) if p.name in (set or {})}
    names = [q.name for q in system.coordinates] + [system.name_of(v) for v in system.state_velocities]
    settings.update({name: repr(v) for name, v in zip(names, values.y0) if name in (set or {})})
    job = make_job(system, plan, dict(system.initial), settings, method=method, t_end=t, dt=dt, rtol=rtol,
                   atol=atol, chunk=chunk or DEFAULT_CHUNK, summaries=tuple(summaries), summary_option="summaries")
    identity = {"system": system.name, "spec": plan.describe(), "set": dict(sorted(settings.items())),
                "method": method, "rtol": rtol, "atol": atol, "t_end": t, "dt": dt, "chunk": job.chunk}
    kept = None
    if trajectories is not None:
        from ..sweep.dataset import Dataset
        from ..sweep.trajectories import trajectory_columns

        kept = Dataset(Path(trajectories), trajectory_columns(system, job.outputs), option="trajectories folder")
        kept.prepare(identity, resume=False, force=force)
        job = dataclasses.replace(job, trajectories=str(kept.folder.resolve()))
    dataset = None
    if output is not None:
        from ..sweep.chunk import columns
        from ..sweep.dataset import Dataset

        dataset = Dataset(Path(output), columns(job), option="output folder")
        dataset.prepare(identity, resume=False, force=force)
    parts: dict[int, pandas.DataFrame] = {}
    tally: dict[str, int] = {}

    def done(index: int, rows: dict) -> None:
        if dataset is None:
            parts[index] = pandas.DataFrame(rows)
            return
        dataset.write(index, rows)  # a chunk at a time: nothing kept here
        for status in rows["status"]:
            tally[status] = tally.get(status, 0) + 1

    execute(job, range(job.chunks), done, scheduler=scheduler or os.environ.get(ENV_SCHEDULER) or None,
            workers=workers)
    if kept is not None:
        kept.write_sidecar({"identity": identity, "state": "complete", "runs": plan.count, "chunks": job.chunks,
                            "columns": [name for name, _ in kept.columns]})
    if dataset is not None:
        dataset.write_sidecar({"identity": identity, "state": "complete", "runs": plan.count, "chunks": job.chunks,
                               "chunks_written": job.chunks, "counts": dataset.counts((), tally),
                               "trajectories": str(kept.folder) if kept is not None else None,
                               "columns": [name for name, _ in dataset.columns]})
        return dataset.folder
    return pandas.concat([parts[i] for i in sorted(parts)], ignore_index=True)
