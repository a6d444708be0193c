"""The clock offset between a prosthesis log and a camera recording, from foot strikes.

The prosthesis controller logs on its own computer and clock; the camera's IMU rides on the
same thigh. Both see every foot strike: the log through its load cell (or its event column),
the camera through its IMU (the offline thigh-IMU detector,
:func:`kinematics.gait_events.detect_from_thigh_imu`). The offset that carries the log's
strikes onto the IMU's strikes is the clock offset (camera time = log time + ``offset_s``).

The steps (:func:`estimate_clock_offset`, a pure function on two arrays of times):

1. remove the expected difference between the two detections of one step (``bias_s`` =
   the IMU detector's bias − the log's lag, both against the true contact) from the camera's
   strikes;
2. every pairwise difference camera − log is a candidate offset; each is scored by how many
   differences lie within ``± tolerance_s`` of it (a sliding window over the sorted
   differences), so an offset of seconds or hours costs the same: no search range is assumed;
3. the best-scoring candidate is refined: each log strike is matched one-to-one to its
   nearest camera strike within the tolerance, the offset moves to the median of the matched
   differences, twice;
4. σ is the spread of the matched differences (1.4826 × MAD, robust to a stray strike); fewer
   than ``min_matches`` matches or a spread above ``max_spread_s`` is a
   :class:`~graph_slam.errors.ClockOffsetError`, and so is a tie with a different offset
   (regular walking repeats itself every stride: an offset one stride off matches almost as
   many strikes; the runner-up's count is reported so the margin can be seen).

Only the camera IMU's own stamps (plus the calibration's ``imu_time_offset_s``) and the log's
strikes are read: no ground truth, no frames.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np

from graph_slam.errors import ClockOffsetError
from graph_slam.session.adapters.config import ClockOffsetConfig
from graph_slam.session.records import ImuSeries

log = logging.getLogger(__name__)

MAD_TO_SIGMA = 1.4826
#: Candidate offsets are all camera × log pairs; beyond this many the search is refused
#: (about 3 000 strikes each, an hour of walking; 8 bytes per pair).
MAX_PAIRS = 10_000_000


@dataclass(frozen=True)
class ClockOffset:
    """The offset used to put a log on the camera clock, and where it came from.

    ``offset_s``: camera time = log time + offset. For ``source == "estimated"`` the other
    fields describe the match: ``sigma_s`` is the spread of one matched difference (1.4826 ×
    MAD), ``standard_error_s`` that of the median (≈ 1.2533 σ / √n), ``bias_s`` what was
    removed, ``runner_up_*`` the best offset at least two tolerances away (the margin).
    """

    offset_s: float
    source: Literal["estimated", "config"]
    sigma_s: float | None = None
    standard_error_s: float | None = None
    n_matched: int | None = None
    n_camera_strikes: int | None = None
    n_log_strikes: int | None = None
    bias_s: float | None = None
    tolerance_s: float | None = None
    runner_up_offset_s: float | None = None
    runner_up_matches: int | None = None

    def describe(self) -> str:
        """One line for the conversion report and the terminal."""
        if self.source == "config":
            return f"clock offset log → camera {self.offset_s:+.4f} s (config: time_offset_s)"
        runner = (
            f"; runner-up {self.runner_up_offset_s:+.3f} s with {self.runner_up_matches}"
            if self.runner_up_offset_s is not None
            else ""
        )
        return (
            f"clock offset log → camera {self.offset_s:+.4f} s, σ {1e3 * (self.sigma_s or 0):.1f} "
            f"ms (estimated: {self.n_matched} foot strikes matched of {self.n_camera_strikes} "
            f"from the camera IMU and {self.n_log_strikes} in the log, within "
            f"±{1e3 * (self.tolerance_s or 0):.0f} ms; expected IMU − log difference "
            f"{1e3 * (self.bias_s or 0):+.1f} ms removed{runner})"
        )

    def to_dict(self) -> dict[str, Any]:
        """Plain values for ``conversion_report.yaml`` (None fields left out)."""
        return {
            k: (float(v) if isinstance(v, float | np.floating) else v)
            for k, v in self.__dict__.items()
            if v is not None
        }


def _strikes(values: np.ndarray, name: str, where: str) -> np.ndarray:
    t = np.sort(np.asarray(values, dtype=np.float64).ravel())
    if not np.all(np.isfinite(t)):
        raise ClockOffsetError(f"{where}: {name} foot strike times must be finite")
    return t


def _window_counts(diffs: np.ndarray, tolerance_s: float) -> np.ndarray:
    """For each sorted difference, how many differences lie within ± tolerance of it."""
    upper = np.searchsorted(diffs, diffs + tolerance_s, side="right")
    lower = np.searchsorted(diffs, diffs - tolerance_s, side="left")
    return upper - lower


def _match(
    camera_s: np.ndarray, log_s: np.ndarray, offset_s: float, tolerance_s: float
) -> np.ndarray:
    """Differences camera − (log + offset) of one-to-one nearest pairs within the tolerance."""
    shifted = log_s + offset_s
    idx = np.searchsorted(camera_s, shifted)
    right = np.clip(idx, 0, camera_s.size - 1)
    left = np.clip(idx - 1, 0, camera_s.size - 1)
    nearest = np.where(
        np.abs(camera_s[left] - shifted) <= np.abs(camera_s[right] - shifted), left, right
    )
    residual = camera_s[nearest] - shifted
    # One-to-one: a camera strike claimed by two log strikes keeps the closer one.
    best: dict[int, int] = {}
    for j in np.flatnonzero(np.abs(residual) <= tolerance_s):
        i = int(nearest[j])
        if i not in best or abs(residual[j]) < abs(residual[best[i]]):
            best[i] = int(j)
    return residual[sorted(best.values())]


@dataclass(frozen=True)
class _Candidate:
    offset_s: float
    residual_s: np.ndarray

    @property
    def n(self) -> int:
        return int(self.residual_s.size)

    @property
    def sigma_s(self) -> float:
        r = self.residual_s
        return MAD_TO_SIGMA * float(np.median(np.abs(r - np.median(r)))) if r.size else np.inf


def _refine(camera: np.ndarray, log_: np.ndarray, offset: float, tol: float) -> _Candidate:
    """Move an offset to the median of its one-to-one matched differences (twice)."""
    for _ in range(2):
        residual = _match(camera, log_, offset, tol)
        if residual.size:
            offset += float(np.median(residual))
    return _Candidate(offset, _match(camera, log_, offset, tol))


def _candidates(
    camera: np.ndarray, log_: np.ndarray, tol: float, peaks: int = 5
) -> list[_Candidate]:
    """The best few distinct offsets (at least 2 tolerances apart) by the number of
    pairwise differences within ± tol, each refined; best first (most matches, then least
    spread)."""
    diffs = np.sort((camera[:, None] - log_[None, :]).ravel())
    counts = _window_counts(diffs, tol)
    found: list[_Candidate] = []
    for _ in range(peaks):
        top = int(np.argmax(counts))
        if counts[top] <= 0:
            break
        centre = diffs[top]
        window = np.abs(diffs - centre) <= tol
        found.append(_refine(camera, log_, float(np.median(diffs[window])), tol))
        counts = np.where(np.abs(diffs - centre) <= 2 * tol, -1, counts)
    found.sort(key=lambda c: (-c.n, c.sigma_s))
    return found


def estimate_clock_offset(
    camera_strikes_s: np.ndarray,
    log_strikes_s: np.ndarray,
    config: ClockOffsetConfig | None = None,
    *,
    where: str = "clock offset",
) -> ClockOffset:
    """The offset (camera = log + offset) that matches the most foot strikes (module docstring).

    ``camera_strikes_s``: strikes detected in the camera's IMU, on the camera clock (IMU
    stamps + ``imu_time_offset_s``), bias not yet removed; ``log_strikes_s``: the log's
    strikes on its own clock. Raises :class:`~graph_slam.errors.ClockOffsetError` when the
    match is too small, too spread or ambiguous.
    """
    cfg = config or ClockOffsetConfig()
    bias_s = cfg.imu_strike_bias_s - cfg.log_strike_lag_s
    camera = _strikes(camera_strikes_s, "camera IMU", where) - bias_s
    log_ = _strikes(log_strikes_s, "log", where)
    need = cfg.min_matched_strikes
    fix = "set prosthesis_log.time_offset_s by hand, or record a longer walk"
    if min(camera.size, log_.size) < need:
        raise ClockOffsetError(
            f"{where}: {camera.size} foot strike(s) detected in the camera IMU and "
            f"{log_.size} in the log; at least {need} matched strikes are needed "
            f"(prosthesis_log.clock.min_matched_strikes): {fix}"
        )
    if camera.size * log_.size > MAX_PAIRS:
        raise ClockOffsetError(
            f"{where}: {camera.size} × {log_.size} strike pairs exceed the search's "
            f"{MAX_PAIRS}; convert a shorter recording or set "
            "prosthesis_log.time_offset_s by hand"
        )
    tol = cfg.tolerance_s
    found = _candidates(camera, log_, tol)
    best = found[0]
    # The runner-up: the best other offset that would also pass the spread bound.
    others = [c for c in found[1:] if abs(c.offset_s - best.offset_s) > 2 * tol]
    plausible = [c for c in others if c.sigma_s <= cfg.max_spread_s] or others
    runner = plausible[0] if plausible else None
    n = best.n
    sigma = best.sigma_s if n else 0.0
    result = ClockOffset(
        offset_s=best.offset_s,
        source="estimated",
        sigma_s=sigma,
        standard_error_s=1.2533 * sigma / np.sqrt(n) if n else None,
        n_matched=n,
        n_camera_strikes=int(camera.size),
        n_log_strikes=int(log_.size),
        bias_s=bias_s,
        tolerance_s=tol,
        runner_up_offset_s=None if runner is None else runner.offset_s,
        runner_up_matches=None if runner is None else runner.n,
    )
    ambiguous = runner is not None and runner.n >= n and runner.sigma_s <= cfg.max_spread_s
    _check(result, cfg, where, fix, ambiguous)
    log.info("%s: %s", where, result.describe())
    return result


def _check(
    result: ClockOffset, cfg: ClockOffsetConfig, where: str, fix: str, ambiguous: bool
) -> None:
    n = result.n_matched or 0
    if n < cfg.min_matched_strikes:
        raise ClockOffsetError(
            f"{where}: only {n} foot strike(s) matched within ±{1e3 * cfg.tolerance_s:.0f} ms "
            f"at the best offset {result.offset_s:+.3f} s ({result.n_camera_strikes} from the "
            f"camera IMU, {result.n_log_strikes} in the log); at least "
            f"{cfg.min_matched_strikes} are needed (prosthesis_log.clock.min_matched_strikes): "
            f"{fix}"
        )
    if ambiguous:
        raise ClockOffsetError(
            f"{where}: ambiguous: offsets {result.offset_s:+.3f} s and "
            f"{result.runner_up_offset_s:+.3f} s both match {n} foot strikes within the spread "
            f"bound (walking at a "
            f"steady pace repeats every stride; a recording that starts or stops walking "
            f"separates them): {fix}"
        )
    if (result.sigma_s or 0.0) > cfg.max_spread_s:
        raise ClockOffsetError(
            f"{where}: the {n} matched foot strikes spread by σ {1e3 * (result.sigma_s or 0):.1f}"
            f" ms (1.4826 × MAD) around the offset {result.offset_s:+.3f} s, above the bound "
            f"{1e3 * cfg.max_spread_s:.1f} ms (prosthesis_log.clock.max_spread_s): the two "
            f"strike sequences do not agree well enough; {fix}"
        )


def camera_imu_strikes(imu: ImuSeries, imu_time_offset_s: float = 0.0) -> np.ndarray:
    """Foot strikes the offline thigh-IMU detector finds in the camera's IMU, on the camera
    clock (IMU stamps + ``imu_time_offset_s``). The IMU may be mounted in any orientation."""
    from kinematics import KinematicsError
    from kinematics.gait_events import GaitEventConfig, detect_from_thigh_imu

    try:
        # the template's strikes: prosthesis_log.clock.imu_strike_bias_s is measured for them
        events = detect_from_thigh_imu(imu, GaitEventConfig(use_impacts=False))
    except KinematicsError as err:
        raise ClockOffsetError(
            f"{imu.source}: foot strikes cannot be detected in the camera IMU ({err}); set "
            "prosthesis_log.time_offset_s by hand"
        ) from None
    return np.asarray(events.foot_strikes_s, dtype=np.float64) + imu_time_offset_s
