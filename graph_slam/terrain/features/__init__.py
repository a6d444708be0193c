"""Terrain features and toe clearance: the records (``model``), their extraction from any
grid (``extract``), the toe's clearance (``clearance``), ``run``'s features file (``io``) and
a benchmark (``python -m graph_slam.terrain.features.bench``)."""
