"""The per-frame grid for the controller: the online elevation map (``online``), its read-only
``view``, the boxes on it (``grid_obstacles``), the carry across a foot strike (``carry``), the
compiled per-frame pass (``kernels``, ``depth_edges``) and the pipelines' component (``live``)."""
