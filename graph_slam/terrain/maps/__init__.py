"""The maps of a stride: fused clouds, an elevation grid, the floor and the boxes on it
(``build_stride_map``), built by ``builder.TerrainBuilder`` from the stride's poses."""
