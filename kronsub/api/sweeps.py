"""Sweeps from a notebook: :func:`sweep`, the rows ``kronsub sweep`` writes, as a DataFrame."""
from __future__ import annotations

import os
from typing import Mapping, Sequence

from ..core.known_system import KnownSystem
from ..core.nonholonomic import refuse_speeds
from .runs import settings_text

__all__ = ["sweep"]


def sweep(system: KnownSystem, grid: Mapping[str, object] | None = None, sample: Mapping[str, str] | None = None,
          runs: int | None = None, seed: int = 0, t: float = 10.0, dt: float = 0.01, method: str = "dop853",
          set: Mapping[str, object] | None = None, rtol: float = 1e-10, atol: float = 1e-10, *,
          latin: bool = False, scheduler: str | None = None, workers: int | None = None, chunk: int | None = None,
          summaries: Sequence[str] = (), trajectories: str | os.PathLike | None = None, force: bool = False):
    """Many runs over a grid (``grid``: name -> ``"a:b:n"``, ``"log:a:b:n"`` or a list of values)
    and a sample (``sample``: name -> ``"uniform(a, b)"``, ``"normal(mu, sd)"``,
    ``"loguniform(a, b)"``, ``runs`` draws) of parameters and initial values, on Dask
    (``scheduler``, else a local cluster of ``workers``): a pandas DataFrame of a row per run,
    as the rows ``kronsub sweep`` writes (:mod:`kronsub.sweep`); ``summaries``: columns of your own
    (``"max(abs(theta))"``, ``"flip=first_time(phi > pi)"``, as ``--summary``); ``trajectories``: a
    folder the workers write every run's rows in (a Parquet dataset, as ``--trajectories``; an
    existing one is refused unless ``force``). It holds every summary row in memory: for sweeps
    larger than memory, the command writes a Parquet dataset a chunk at a time."""
    refuse_speeds(system, "sweep")
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
    names = [q.name for q in system.coordinates] + [system.name_of(v) for v in system.velocities]
    settings.update({name: repr(v) for name, v in zip(names, values.y0) if name in (set or {})})
    job = make_job(system, plan, dict(system.initial), settings, method=method, t_end=t, dt=dt, rtol=rtol,
                   atol=atol, chunk=chunk or DEFAULT_CHUNK, summaries=tuple(summaries), summary_option="summaries")
    kept = None
    if trajectories is not None:
        from ..sweep.dataset import Dataset
        from ..sweep.trajectories import trajectory_columns

        kept = Dataset(Path(trajectories), trajectory_columns(system, job.outputs), option="trajectories folder")
        identity = {"system": system.name, "spec": plan.describe(), "set": dict(sorted(settings.items())),
                    "method": method, "rtol": rtol, "atol": atol, "t_end": t, "dt": dt, "chunk": job.chunk}
        kept.prepare(identity, resume=False, force=force)
        job = dataclasses.replace(job, trajectories=str(kept.folder.resolve()))
    parts: dict[int, pandas.DataFrame] = {}
    execute(job, range(job.chunks), lambda index, rows: parts.__setitem__(index, pandas.DataFrame(rows)),
            scheduler=scheduler or os.environ.get(ENV_SCHEDULER) or None, workers=workers)
    if kept is not None:
        kept.write_sidecar({"identity": identity, "state": "complete", "runs": plan.count, "chunks": job.chunks,
                            "columns": [name for name, _ in kept.columns]})
    return pandas.concat([parts[i] for i in sorted(parts)], ignore_index=True)
