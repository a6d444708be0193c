"""The frames of a bag: which colour is used (as recorded, registered here, or dropped), the
pairing of depth frames with colour images, and the frame-by-frame second pass over the bag
that decodes, checks and registers each image."""

from __future__ import annotations

from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from graph_slam.errors import BagError, ConversionError
from graph_slam.session.adapters.align import CameraModel, align_color_to_depth, pixel_rays
from graph_slam.session.adapters.bag_calibration import BagCalibration
from graph_slam.session.adapters.bag_images import decode_image
from graph_slam.session.adapters.bag_reader import Bag
from graph_slam.session.adapters.bag_scan import Collected
from graph_slam.session.adapters.bag_topics import TopicChoice
from graph_slam.session.adapters.base import ConversionReport, StreamReport
from graph_slam.session.adapters.config import BagConfig, ConvertConfig
from graph_slam.session.adapters.timing import associate, order_stamps
from graph_slam.session.records import RgbdFrame


@dataclass(frozen=True)
class ColorPlan:
    """How colour is written: as recorded (registered) or registered to depth here."""

    use: bool
    depth_model: CameraModel | None = None
    color_model: CameraModel | None = None
    color_T_depth: np.ndarray | None = None

    @property
    def align(self) -> bool:
        return self.use and self.color_T_depth is not None


def color_plan(
    path: Path,
    choice: TopicChoice,
    got: Collected,
    cfg: BagConfig,
    calib: BagCalibration,
    depth_model: CameraModel,
    report: ConversionReport,
) -> ColorPlan:
    """Use colour as recorded when it is registered to depth; else register it when the bag
    (or the config) has the colour camera and the depth→colour extrinsics; else drop it."""
    if choice.color is None:
        return ColorPlan(False)
    width, height = got.depth_format[1:]
    if choice.color_registered:
        if got.color_format is not None and got.color_format[1:] != (width, height):
            raise ConversionError(
                f"{path}: colour on {choice.color} is {got.color_format[1]}×"
                f"{got.color_format[2]}, depth is {width}×{height}; registered colour "
                "must have the depth's size"
            )
        return ColorPlan(True)
    missing = []
    if not cfg.align_color:
        missing.append("bag.align_color is false")
    if calib.color_model is None:
        missing.append("no colour camera_info (bag.color_info_topic)")
    if calib.color_T_depth is None:
        missing.append("no depth→colour extrinsics in the bag (bag.color_T_depth)")
    if missing:
        reason = "not registered to depth: " + "; ".join(missing)
        report.add(
            StreamReport("color", choice.color, len(got.color_ns), 0, {reason: len(got.color_ns)})
        )
        return ColorPlan(False)
    if got.color_format is not None and got.color_format[1:] != (
        calib.color_model.width_px,
        calib.color_model.height_px,
    ):
        raise ConversionError(
            f"{path}: colour on {choice.color} is {got.color_format[1]}×{got.color_format[2]} "
            f"but {choice.color_info} says {calib.color_model.width_px}×"
            f"{calib.color_model.height_px}"
        )
    report.notes.append(
        f"colour registered to depth here ({calib.color_model.distortion_model} colour camera, "
        f"color_T_depth from {calib.color_T_depth.source})"
    )
    return ColorPlan(True, depth_model, calib.color_model, calib.color_T_depth.pose)


def nearest_within(
    t_ref_s: np.ndarray, t_other_s: np.ndarray, max_dt_s: float
) -> tuple[np.ndarray, np.ndarray]:
    """Each reference sample paired with the nearest other sample within ``max_dt_s`` (an
    other sample may serve several references)."""
    if t_ref_s.size == 0 or t_other_s.size == 0:
        return np.zeros(0, dtype=np.intp), np.zeros(0, dtype=np.intp)
    j = np.clip(np.searchsorted(t_other_s, t_ref_s), 1, t_other_s.size - 1)
    if t_other_s.size == 1:
        j = np.zeros_like(j)
    else:
        earlier = np.abs(t_ref_s - t_other_s[j - 1]) <= np.abs(t_other_s[j] - t_ref_s)
        j = np.where(earlier, j - 1, j)
    ok = np.abs(t_other_s[j] - t_ref_s) <= max_dt_s
    return np.flatnonzero(ok), j[ok]


def pair_frames(
    choice: TopicChoice,
    got: Collected,
    config: ConvertConfig,
    plan: ColorPlan,
    report: ConversionReport,
) -> tuple[np.ndarray, np.ndarray | None, StreamReport]:
    """Depth frames in stamp order, each paired with a colour image when colour is used."""
    depth_ns = np.asarray(got.depth_ns, dtype=np.int64)
    d_order = order_stamps(depth_ns)
    depth_kept = d_order.keep  # message positions, in stamp order
    frames_dropped = {"duplicate stamp": d_order.duplicates}
    color_pos = None
    if plan.use:
        color_ns = np.asarray(got.color_ns, dtype=np.int64)
        c_order = order_stamps(color_ns)
        max_dt = config.association.max_color_dt_s
        ns0 = int(depth_ns.min())
        if config.association.share_color:
            i_d, i_c = nearest_within(
                (depth_ns[depth_kept] - ns0) * 1e-9, (color_ns[c_order.keep] - ns0) * 1e-9, max_dt
            )
        else:
            i_d, i_c = associate(
                (depth_ns[depth_kept] - ns0) * 1e-9,
                (color_ns[c_order.keep] - ns0) * 1e-9,
                max_dt,
            )
        # Every depth frame is kept: one without a colour image within max_dt is written
        # depth-only (position -1), counted; the pipeline registers it without colour.
        color_pos = np.full(depth_kept.size, -1, dtype=np.int64)
        color_pos[i_d] = c_order.keep[i_c]
        depth_only = depth_kept.size - i_d.size
        report.add(
            StreamReport(
                "color",
                choice.color,
                color_ns.size,
                int(i_c.size),
                {
                    "duplicate stamp": c_order.duplicates,
                    f"no depth frame within {max_dt} s": c_order.keep.size - i_c.size,
                },
            )
        )
    frames_report = report.add(
        StreamReport("frames", choice.depth, depth_ns.size, depth_kept.size, frames_dropped)
    )
    if color_pos is not None and depth_only:
        frames_report.notes.append(
            f"{depth_only} depth frame(s) without a colour image within "
            f"{config.association.max_color_dt_s} s kept depth-only"
        )
        frames_report.depth_only = depth_only
    return depth_kept, color_pos, frames_report


# --------------------------------------------------------------------------- the second pass
@dataclass(frozen=True)
class FrameSource:
    """What the second pass reads: the bag, the chosen message positions (in frame order), and
    the format every decoded image must have (the first pass's encoding and size)."""

    path: Path
    choice: TopicChoice
    msgtypes: Mapping[str, str | None]
    depth_pos: np.ndarray
    color_pos: np.ndarray | None
    frame_t: np.ndarray
    unit_m: float
    depth_format: tuple[str, int, int]
    color_format: tuple[str, int, int] | None
    plan: ColorPlan

    @property
    def n_frames(self) -> int:
        return int(self.depth_pos.size)


@dataclass
class FrameCounts:
    """Pixels repaired or left without colour in the second pass (for the frames' notes)."""

    non_finite: int = 0
    no_depth: int = 0
    outside: int = 0
    #: frames yielded so far
    written: int = field(default=0)


def frame_reader(
    src: FrameSource, frames_report: StreamReport
) -> Callable[[], Iterator[RgbdFrame]]:
    """A callable yielding the frames in stamp order (second pass over the bag); when it is
    exhausted the frames' notes in ``frames_report`` carry the pixel counts."""

    def frames() -> Iterator[RgbdFrame]:
        counts = FrameCounts()
        yield from _read_frames(src, counts)
        frame_notes(frames_report, counts, src.plan)
        if counts.written != src.n_frames:
            raise BagError(
                f"{src.path}: the second pass found {counts.written} of {src.n_frames} frames; "
                "the bag changed or is damaged while converting"
            )

    return frames


def _read_frames(src: FrameSource, counts: FrameCounts) -> Iterator[RgbdFrame]:
    """Decode the chosen messages and yield each frame as soon as its depth (and colour) is in."""
    choice, plan = src.choice, src.plan
    frame_of_depth = {int(p): k for k, p in enumerate(src.depth_pos)}
    frames_of_color: dict[int, list[int]] = {}
    for k, p in enumerate(() if src.color_pos is None else src.color_pos):
        if p >= 0:
            frames_of_color.setdefault(int(p), []).append(k)
    depth_only = (
        set() if src.color_pos is None else {k for k, p in enumerate(src.color_pos) if p < 0}
    )
    rays = pixel_rays(plan.depth_model) if plan.align else None
    with_color = src.color_pos is not None and choice.color is not None
    depth_ready: dict[int, np.ndarray] = {}
    color_ready: dict[int, np.ndarray] = {}
    topics = {choice.depth} | ({choice.color} if with_color else set())
    position = dict.fromkeys(topics, -1)
    with Bag(src.path) as bag:
        for topic, _, msg in bag.messages(topics):
            position[topic] += 1
            pos = position[topic]
            if topic == choice.depth and pos in frame_of_depth:
                raw = _decoded(src, msg, topic, pos, "depth")
                depth_ready[frame_of_depth[pos]] = depth_m(raw, src.unit_m, counts)
            if topic == choice.color and pos in frames_of_color:
                image = _decoded(src, msg, topic, pos, "color")
                for k_color in frames_of_color[pos]:
                    color_ready[k_color] = image
            k = counts.written
            while (
                k < src.n_frames
                and k in depth_ready
                and (not with_color or k in color_ready or k in depth_only)
            ):
                yield _frame(src, k, depth_ready.pop(k), color_ready.pop(k, None), rays, counts)
                k = counts.written = k + 1


def _decoded(src: FrameSource, msg, topic: str, pos: int, role: str) -> np.ndarray:
    """Decode one image and check it against the stream's format: a compressed image's size
    is known from the topic's first message only, so a later one of another size (or kind)
    is an error naming the topic and the message index, never a frame of another shape."""
    array = decode_image(msg, src.msgtypes.get(topic), topic, pos, role)
    fmt = src.depth_format if role == "depth" else src.color_format
    if fmt is None:  # not reached: a used stream has a format from the first pass
        return array
    encoding, width, height = fmt
    if role == "depth":
        shape, dtype = (height, width), np.dtype(np.float32 if encoding == "32FC1" else np.uint16)
    else:
        shape, dtype = (height, width, 3), np.dtype(np.uint8)
    if array.shape != shape or array.dtype != dtype:
        raise ConversionError(
            f"{src.path}: topic {topic}, message {pos}: the {role} image decodes to shape "
            f"{array.shape} {array.dtype}, but the topic's first message is {width}×{height} "
            f"({encoding!r}, {shape} {dtype}); every image of a topic must have one size"
        )
    return array


def _frame(
    src: FrameSource,
    k: int,
    depth: np.ndarray,
    color: np.ndarray | None,
    rays: np.ndarray | None,
    counts: FrameCounts,
) -> RgbdFrame:
    """Frame ``k``: colour registered to depth here when the plan says so."""
    plan = src.plan
    if plan.align and color is not None:
        aligned = align_color_to_depth(
            depth, color, plan.depth_model, plan.color_model, plan.color_T_depth, rays
        )
        counts.no_depth += aligned.no_depth
        counts.outside += aligned.outside
        color = aligned.color_rgb
    return RgbdFrame(t_s=float(src.frame_t[k]), depth_m=depth, color_rgb=color, index=k)


def depth_m(raw: np.ndarray, unit_m: float, counts: FrameCounts) -> np.ndarray:
    """Raw depth → metres (float32); NaN, inf or negative float depth → 0 (no reading), counted."""
    scale = np.float32(unit_m)
    if raw.dtype == np.float32:
        bad = ~np.isfinite(raw) | (raw < 0)
        counts.non_finite += int(bad.sum())
        return np.where(bad, 0.0, raw).astype(np.float32) * scale
    return raw.astype(np.float32) * scale


def frame_notes(frames_report: StreamReport, counts: FrameCounts, plan: ColorPlan) -> None:
    """The second pass's pixel counts, as notes of the ``frames`` stream."""
    if counts.non_finite:
        frames_report.notes.append(
            f"{counts.non_finite} depth pixel(s) NaN, inf or negative written as 0 "
            "(no reading, REP 118)"
        )
    if plan.align:
        frames_report.notes.append(
            f"colour registered to depth: {counts.outside} depth pixel(s) with a reading "
            f"project outside the colour image (written black); {counts.no_depth} without "
            "a reading get no colour (black)"
        )
