"""Batch studies on Dask: every session × variant × configuration of a spec as one task.

    from graph_slam.batch import ClusterOptions, run_batch
    result = run_batch("study.yaml", "runs/study", ClusterOptions(workers=2))

Dask (the optional extra ``graph_slam[batch]``) is imported only when a batch runs; the
estimator never imports it. See docs/batch.md.
"""

from graph_slam.batch.run import BatchResult, ClusterOptions, run_batch
from graph_slam.batch.spec import BatchSpec, load_spec

__all__ = ["BatchResult", "BatchSpec", "ClusterOptions", "load_spec", "run_batch"]
