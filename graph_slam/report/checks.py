"""compare's checks before and after the run: refuse what would be meaningless, list caveats.

:func:`preflight` runs before any work (every session's plausibility and the streams each
variant needs; :mod:`graph_slam.session.plausibility`); :func:`run_warnings` adds what only the
run knows (strides dropped and why, samples rejected by reason). Both return
:class:`~graph_slam.session.plausibility.Finding` s, written to report.md and metrics.json.
"""

from __future__ import annotations

from collections import Counter
from pathlib import Path

import numpy as np
import yaml

from graph_slam.session.plausibility import (
    Finding,
    raise_fatal,
    session_findings,
    variant_findings,
)


def preflight(
    sessions, variants: list[str], event_source: str | None, *, scoring: bool = True
) -> list[Finding]:
    """Raise a :class:`SessionError` for the first fatal finding, or an
    :class:`EvaluationError` when scoring needs evo and it is missing (``scoring``: a session
    has ground truth and will be scored; ``run`` never scores); return the caveats."""
    from graph_slam.evaluation._evo import require_evo
    from graph_slam.strides.events import stride_events
    from graph_slam.strides.online_events import ONLINE_SOURCE

    if scoring and any(s.ground_truth is not None for s in sessions):
        require_evo()  # the optional extra, before minutes of work rather than after
    from_events = event_source != ONLINE_SOURCE
    found: list[Finding] = []
    for session in sessions:
        found += variant_findings(session, variants, events_cut_strides=from_events)
        found += session_findings(session, events_cut_strides=from_events)
    caveats = raise_fatal(found)
    for session in sessions if from_events else []:  # the event source must be in events.csv
        stride_events(session.events, event_source, str(session.path / "events.csv"))
    return caveats


def _dropped_strides(session, run, event_source: str | None) -> list[Finding]:
    """Strides the run cut that no table scores, counted by reason (the rules of
    :func:`graph_slam.strides.reference.stride_references`)."""
    from graph_slam.strides.reference import _cut_short
    from graph_slam.strides.streams import session_streams

    first = next(iter(run.results.values()))
    events = session_streams(session, event_source).events  # as SessionRun.build reads them
    scored = {int(r.frame_indices[0]) for r in run.references}
    t = np.asarray(first.t_s)
    why: Counter[str] = Counter()
    for s in first.strides:
        idx = np.asarray(s.frame_indices, dtype=int)
        if not idx.size or int(idx[0]) in scored:
            continue
        if s.start != "foot_strike" or events.last_strike_at_or_before(float(t[idx[0]])) is None:
            continue  # the part before the first foot strike is no stride
        last = events.next_strike_after(float(t[idx[-1]])) is None
        if last and int(idx[-1]) == session.n_frames - 1:
            continue  # the recording's tail after its last strike, like its head: no stride
        if idx.size < 2:
            why["fewer than 2 frames"] += 1
        elif _cut_short(idx, t, session):
            why["the run stopped inside it"] += 1
        elif session.ground_truth is None:
            why["no ground truth"] += 1
        elif last:
            why["no foot strike after it"] += 1
        else:
            why["other"] += 1
    if not why:
        return []
    detail = ", ".join(f"{n} {k}" for k, n in sorted(why.items()))
    return [
        Finding(
            "strides_dropped",
            str(session.path),
            f"{sum(why.values())} strides not scored ({detail}); {len(run.references)} scored",
        )
    ]


def rejected_samples(session, results: dict) -> list[Finding]:
    """Per variant: the IMU and encoder samples its pipeline rejected, by reason, and the
    foot strikes too close to the previous one (:mod:`graph_slam.pipelines.strikes`)."""
    from graph_slam.pipelines.strikes import MIN_STRIKE_INTERVAL_S, TOO_CLOSE_KEY

    out = []
    for variant, res in results.items():
        bad = {
            k: v
            for k, v in res.counts.items()
            if v and k.startswith(("imu_", "joints_")) and not k.endswith("_used")
        }
        too_close = res.counts.get(TOO_CLOSE_KEY, 0)
        if too_close:
            out.append(
                Finding(
                    "strikes_too_close",
                    str(session.path),
                    f"variant {variant}: {too_close} foot strike(s) less than "
                    f"{MIN_STRIKE_INTERVAL_S:g} s after the previous one (each cut a stride "
                    "there)",
                )
            )
        if bad:
            detail = ", ".join(f"{k} {v}" for k, v in sorted(bad.items()))
            out.append(
                Finding("samples_rejected", str(session.path), f"variant {variant}: {detail}")
            )
    return out


def run_warnings(session, run, event_source: str | None) -> list[Finding]:
    """Caveats only the run knows: strides dropped and why, samples rejected by reason."""
    return _dropped_strides(session, run, event_source) + rejected_samples(session, run.results)


def write_compare_config(cfg, path: Path) -> Path:
    """The resolved config; ``pipeline.variant`` is left out (each run sets it from
    ``variants``), so the file never names a variant that did not run."""
    data = cfg.model_dump(mode="json")
    data["pipeline"].pop("variant", None)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(
        "# pipeline.variant is set per run from 'variants' below\n"
        + yaml.safe_dump(data, sort_keys=False),
        encoding="utf-8",
    )
    return path
