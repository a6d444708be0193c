"""The thresholds of the terrain features' extraction (:mod:`graph_slam.terrain.features.model`
describes the steps they govern)."""

from __future__ import annotations

from pydantic import Field

from graph_slam.config import ConfigModel


class FeatureConfig(ConfigModel):
    """Thresholds of :func:`extract_features` (metres, degrees)."""

    max_noise_sigma_m: float = Field(
        0.02,
        gt=0,
        description="a cell whose depth-noise σ exceeds this is not seen: beyond a down-step's "
        "nosing the cells hold only the flying pixels of the depth edge (their σ 5-12 cm "
        "against 0.3-2.5 mm on a surface, their heights near the upper tread's), which put "
        "the nosing a cell late",
    )
    shadow_cell_seen: float = Field(
        0.65,
        ge=0,
        le=1,
        description="where a nosing's shadow begins: this part of the last cell seen before it "
        "(a cell is seen once about a quarter of it lies before the shadow: the edge lies in "
        "its last 0.25-1, 0.625 on average)",
    )
    shadow_cell_sigma: float = Field(
        0.22, ge=0, description="σ of that part (uniform over 0.25-1 of a cell: 0.75/√12)"
    )
    shadow_from_counts: bool = Field(
        True,
        description="where the grid's point counts are known, the part of the last cell seen "
        "before a shadow is its count over the mean count of the two cells before it (points "
        "fall evenly on a tread: a cell seen over a part f of its length holds about f of its "
        "neighbour's points); shadow_cell_seen where they are not",
    )
    shadow_count_min: int = Field(
        8, ge=1, description="fewest points in the cells before it for that ratio"
    )
    shadow_count_sigma: float = Field(
        0.1, ge=0, description="σ of the part from the counts (a cell), common to the rows"
    )
    shadow_count_common: float = Field(
        0.35,
        ge=0,
        le=1,
        description="correlation of two nosings of one flight whose shadow parts both come "
        "from the counts (the same flying pixels' share and density trend of the points, "
        "alike from nosing to nosing): a tread between them has the variance "
        "σ1² + σ2² - 2ρσ1σ2. Consecutive descending nosings' errors correlate 0.18-0.63 "
        "(0.35 pooled over seeds 3 and 4 and all speeds) on the simulated terrain walker",
    )
    shadow_sparse_fraction: float = Field(
        0.0,
        ge=0,
        le=1,
        description="beyond a drop, a cell of the far surface holding fewer points than this "
        "fraction of the mean count of the two near cells before the edge lies in the shadow "
        "for all but a few late viewpoints (the camera over the edge) and counts as not seen "
        "(the part of the last near cell seen, from the counts, places the edge). 0 (off): "
        "on the simulated terrain walker 0.25 moved the curbs down's edges from 7 mm late to "
        "0.5 mm early, but a 4 cm box's far edge from 2.3 mm late to 6.9 mm early (the flying "
        "pixels of the edge leave the last top cell short of points)",
    )
    sparse_span_fraction: float = Field(
        0.25,
        ge=0,
        le=1,
        description="beyond a drop, a far cell holding fewer points than this fraction of the "
        "two near cells' mean count is seen only from a few late viewpoints (the camera over "
        "the edge): it may hold the far surface or a part of the edge, so the edge lies "
        "between the reading that takes it as seen and the one that takes it as not seen "
        "(shadow_sparse_fraction); 0: no such σ term",
    )
    sparse_span_sigma: float = Field(
        0.5,
        ge=0,
        description="σ of an edge beyond a drop, as a part of the span between those two "
        "readings, common to its rows (either reading as likely: the error is 0 or the span, "
        "its spread half the span)",
    )
    carried_edge_sigma_m: float = Field(
        0.003,
        ge=0,
        description="σ of an edge seen only in cells carried from the previous stride (no "
        "point of this stride on either side of it), common to its rows: the carry moves "
        "it by the estimated relative stride pose's horizontal error, which the cells' "
        "height σ does not hold. That error along x over 46 foot strikes of the simulated "
        "terrain walker (23 walks): RMS 3.0 mm (mean +2.3). Two edges carried by the same "
        "pose share it: it cancels in the tread between them",
    )
    stride_tilt_sigma_rad: float = Field(
        0.0017,
        ge=0,
        description="σ of the stride frame's tilt along x: a tilt moves two terraces' heights "
        "apart by it times the distance between where their heights lie (their cells' "
        "inverse-variance mean x), the same in every cell of each, so a rise's or a box "
        "height's σ carries it however many cells are averaged. The level surfaces of the "
        "simulated terrain walker's stride maps lean 1.65 mrad RMS along x (71 surfaces, "
        "22 walks, 3 strides each)",
    )
    face_cell_sigma: float = Field(
        0.2887,
        ge=0,
        description="an edge seen face-on (a rise's riser, a box's front): the face's points "
        "all fall in the cell holding the edge (or split between it and a neighbour), about "
        "halfway up the step, so that cell's height says where the face's points are, not "
        "where the edge lies in it: the edge is off by up to r/2 of a cell, r the share of "
        "the cell's points on the face (its count over the surface cells' either side), the "
        "same in every row of an edge along the grid. Its σ is this part of a cell (uniform "
        "over it: 1/√12) times r, common to the rows; 0: no such term",
    )
    window_cells: int = Field(5, ge=3, le=11, description="local plane window (odd)")
    min_window_cells: int = Field(12, ge=3, description="known cells a local plane needs")
    level_max_deg: float = Field(3.0, gt=0, description="steepest level cell")
    ramp_min_deg: float = Field(3.5, gt=0, description="gentlest ramp cell")
    ramp_max_deg: float = Field(20.0, gt=0, description="steepest ramp cell")
    fit_rms_max_m: float = Field(0.006, gt=0, description="local plane residual of a surface")
    min_terrace_cells: int = Field(6, ge=1)
    min_ramp_cells: int = Field(20, ge=3)
    min_ramp_length_m: float = Field(0.2, gt=0, description="a ramp's extent up its slope")
    grow_cells: int = Field(3, ge=0, description="cells a terrace grows by towards its edges")
    grow_tol_m: float = Field(0.01, gt=0, description="height of a cell a terrace grows into")
    min_rise_m: float = Field(0.03, gt=0, description="smallest step, curb or box")
    max_gap_cells: int = Field(10, ge=0, description="most cells between two terraces")
    min_edge_rows: int = Field(3, ge=2, description="rows an edge must be seen in")
    box_same_level_m: float = Field(0.02, gt=0)
    curb_min_depth_m: float = Field(0.45, gt=0, description="upper surface of a curb")
