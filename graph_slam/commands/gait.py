"""Gait commands: ``gait-events`` (foot strikes and toe-offs from a thigh IMU CSV)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer


def register(app: typer.Typer) -> None:
    @app.command("gait-events")
    def gait_events(
        imu_csv: Annotated[
            Path,
            typer.Argument(
                help="IMU CSV as a session's imu.csv: t_s,gyro_x_rad_s,gyro_y_rad_s,gyro_z_rad_s,"
                "accel_x_m_s2,accel_y_m_s2,accel_z_m_s2 (or the legacy t_s,gyro_x,...,accel_z; "
                "50-1000 Hz), from a thigh IMU in any orientation."
            ),
        ],
        out: Annotated[
            Path | None,
            typer.Option("--out", help="Write t_s,kind rows here (default: standard output)."),
        ] = None,
        online: Annotated[
            bool,
            typer.Option(
                "--online",
                help="Use the causal estimator (kinematics.gait_phase: one sample at a time, no "
                "look-ahead) and write t_s,kind,detected_t_s rows (estimated event time, kind, "
                "time of the sample at which it was emitted).",
            ),
        ] = False,
    ) -> None:
        """Detect foot strikes and toe-offs from a thigh IMU alone (kinematics.gait_events;
        --online: kinematics.gait_phase)."""
        import logging

        from graph_slam.session.atomic import check_output_file
        from kinematics.gait_events import (
            detect_from_thigh_imu,
            read_imu_csv,
            write_events_csv,
        )

        if not logging.getLogger().handlers:
            logging.basicConfig(level=logging.WARNING, format="warning: %(message)s")
        if out is not None:
            check_output_file(out, inputs=[imu_csv])  # before any work
        imu = read_imu_csv(imu_csv)
        if online:
            _online(imu_csv, imu, out)
            return
        events = detect_from_thigh_imu(imu)
        if out is not None:
            write_events_csv(out, events)
        else:
            typer.echo("t_s,kind")
            for t, kind in events.rows():
                typer.echo(f"{t:.6f},{kind}")
        axis = events.sagittal_axis
        axis_text = "–" if axis is None else "[" + ", ".join(f"{a:+.3f}" for a in axis) + "]"
        typer.echo(
            f"{imu_csv}: {events.foot_strikes_s.size} foot strikes, {events.toe_offs_s.size} "
            f"toe-offs; {events.merged_strikes} foot strikes merged (closer than the minimum "
            f"stride time), {events.rejected} candidates rejected; sagittal axis (sensor "
            f"frame, flexion +) {axis_text}; {_impact_text(events.details)}"
            + (f"; wrote {out}" if out is not None else ""),
            err=True,
        )


def _impact_text(details: dict) -> str:
    """How the strikes were placed and how the sign was decided (offline detector)."""
    n = int(details.get("impact_strikes", 0))
    if n == 0:
        return "no heel-strike shocks: strikes from the template fit"
    text = f"{n} strikes on heel-strike shocks (burst ratio {details['burst_ratio']:.1f})"
    if details.get("sign_disagreement"):
        text += "; FLAG: the template fit chose the other flexion sign"
    return text


def _online(imu_csv: Path, imu, out: Path | None) -> None:
    from kinematics.gait_online import estimate_online, write_online_events_csv

    result = estimate_online(imu)
    if out is not None:
        write_online_events_csv(out, result.events)
    else:
        typer.echo("t_s,kind,detected_t_s")
        for e in result.events:
            typer.echo(f"{e.t_s:.6f},{e.kind},{e.detected_t_s:.6f}")
    n_fs = sum(e.kind == "foot_strike" for e in result.events)
    if result.counts.get("sign_disagreement"):
        typer.echo(
            f"{imu_csv}: FLAG: the flexion sign was re-examined and flipped "
            f"{result.counts['axis_flipped']} time(s) (see docs/kinematics.md)",
            err=True,
        )
    counts = ", ".join(f"{k} {v}" for k, v in result.counts.items())
    delays = [e.detected_t_s - e.t_s for e in result.events]
    delay = f"{1e3 * max(delays):.0f} ms" if delays else "–"
    typer.echo(
        f"{imu_csv}: online: {n_fs} foot strikes, {len(result.events) - n_fs} toe-offs; "
        f"longest detection delay {delay}; strike bias {1e3 * result.strike_bias_s:+.0f} ms "
        f"learned from {result.strike_bias_source}; {counts}" + (f"; wrote {out}" if out else ""),
        err=True,
    )
