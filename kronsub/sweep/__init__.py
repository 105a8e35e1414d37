"""Sweeps: many runs of one model over a grid or a sample of its parameters and initial values,
each run summarised in a row (:mod:`.chunk`), computed a chunk at a time as Dask tasks
(:mod:`.driver`) by a compiled ensemble (:mod:`.ensemble`: one library, a block of runs a call)
and written as a Parquet dataset with a JSON sidecar (:mod:`.dataset`). The axes are read by
:mod:`.axes`, the runs numbered and their inputs drawn by :mod:`.plan`, and the study set up
from a derived model by :mod:`.study`."""
