"""Same input, same numbers: the thread settings that make a run repeat bit for bit.

The one source of run-to-run differences found on this stack is Open3D's CPU parallelism:
Open3D 0.20 runs its reductions (the ICP's ``JᵀJ`` and ``Jᵀr`` sums, normals, covariances)
with oneTBB's ``parallel_reduce`` and an automatic partitioner, whose split points depend
on which thread steals which piece, so the order of a sum, and its last digits, change from
run to run. ``OMP_NUM_THREADS`` does not reach it (Open3D 0.20 uses no OpenMP). A last digit
can flip a gate, a keyframe or a stop decision, and the stride's error then differs by
millimetres. GTSAM's wheel is built without TBB (its elimination is single-threaded); the
numba kernels and small_gicp (``num_threads`` 1) are serial; every generator is seeded.

:func:`apply_threads` bounds Open3D to one thread when a run is deterministic
(``PipelineConfig.deterministic``, the default) and lifts the bound otherwise. The bound is
process-wide (``open3d.utility.set_max_threads``): every pipeline that
:func:`graph_slam.pipelines.runner.make_pipeline` builds sets it for its own run.
"""

from __future__ import annotations

OPEN3D_DETERMINISTIC_THREADS = 1
"""Open3D's thread bound in a deterministic run (its reductions' order is then fixed)."""


def apply_threads(deterministic: bool = True) -> None:
    """Bound Open3D's threads to one (``deterministic``) or lift the bound (its automatic
    default: every core the process may use)."""
    import open3d as o3d

    o3d.utility.set_max_threads(OPEN3D_DETERMINISTIC_THREADS if deterministic else 0)


def open3d_threads() -> int:
    """The number of threads Open3D may use now."""
    import open3d as o3d

    return int(o3d.utility.get_max_threads())
