"""The project's own sources: a session folder, and the analytic synthetic source.

Converting a session into a session re-encodes it (e.g. with another depth unit); the synthetic
source (``--format synthetic``, SRC a YAML of :class:`SyntheticConfig` overrides, may be empty)
gives a conversion whose every sample is known exactly.
"""

from __future__ import annotations

from pathlib import Path

from graph_slam.config import load_config
from graph_slam.session.adapters.base import ConversionReport, Recording, StreamReport
from graph_slam.session.adapters.config import ConvertConfig
from graph_slam.session.manifest import MANIFEST_NAME
from graph_slam.session.reader import Session


def _counted(report: ConversionReport, name: str, source: str, n: int) -> None:
    report.add(StreamReport(name, source, n, n))


class SessionAdapter:
    """A graph_slam session folder (holds session.yaml)."""

    name = "session"
    summary = "a graph_slam session folder (re-encode, e.g. with another depth unit)"

    def detect(self, path: Path) -> bool:
        return path.is_dir() and (path / MANIFEST_NAME).is_file()

    def open(self, path: Path, config: ConvertConfig) -> Recording:
        session = Session(path)
        report = ConversionReport(adapter=self.name, source=str(path))
        _counted(report, "frames", session.manifest.files.frames, session.n_frames)
        for stream in ("imu", "joints", "events", "ground_truth", "ground_truth_hf"):
            value = getattr(session, stream)
            if value is not None:
                _counted(report, stream, str(getattr(session.manifest.files, stream)), len(value))
        cam = session.manifest.sensors.camera
        imu = session.manifest.sensors.imu
        return Recording(
            name=session.name,
            report=report,
            resolved=config.model_copy(update={"format": self.name}),
            intrinsics=session.intrinsics,
            depth_unit_m=config.output.depth_unit_m or session.depth_unit_m,
            frame_times_s=session.frame_times_s,
            frames=session.iter_frames,
            imu=session.imu,
            joints=session.joints,
            events=session.events,
            ground_truth=session.ground_truth,
            ground_truth_hf=session.ground_truth_hf,
            calibration=session.calibration,
            camera_profile="unknown" if cam is None else cam.profile,
            imu_profile="unknown" if imu is None else imu.profile,
        )


class SyntheticAdapter:
    """The analytic synthetic source; SRC is a YAML file of SyntheticConfig overrides."""

    name = "synthetic"
    summary = "analytic synthetic session (SRC: YAML of SyntheticConfig overrides; explicit only)"

    def detect(self, path: Path) -> bool:
        return False  # only by --format synthetic

    def open(self, path: Path, config: ConvertConfig) -> Recording:
        from graph_slam.session.synthetic import (
            SyntheticConfig,
            intrinsics_for,
            iter_synthetic_frames,
            synthetic_streams,
        )

        cfg = load_config(SyntheticConfig, path)
        streams = synthetic_streams(cfg)
        report = ConversionReport(adapter=self.name, source=str(path))
        _counted(report, "frames", "synthetic", streams.frame_times_s.size)
        _counted(report, "imu", "synthetic", len(streams.imu))
        _counted(report, "joints", "synthetic", len(streams.joints))
        _counted(report, "events", "synthetic", len(streams.events))
        _counted(report, "ground_truth", "synthetic", len(streams.ground_truth))
        _counted(report, "ground_truth_hf", "synthetic", len(streams.ground_truth_hf))
        return Recording(
            name=f"synthetic-seed{cfg.seed}",
            report=report,
            resolved=config.model_copy(update={"format": self.name}),
            intrinsics=intrinsics_for(cfg),
            depth_unit_m=config.output.depth_unit_m or cfg.depth_unit_m,
            frame_times_s=streams.frame_times_s,
            frames=lambda: iter_synthetic_frames(cfg),
            imu=streams.imu,
            joints=streams.joints,
            events=streams.events,
            ground_truth=streams.ground_truth,
            ground_truth_hf=streams.ground_truth_hf,
            calibration=streams.calibration,
            camera_profile="synthetic",
            imu_profile="synthetic",
        )
