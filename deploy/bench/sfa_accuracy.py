"""Accuracy of the sensor fusion for ``ato bench sfa`` (issue 8): lockstep drives of the whole
chain (emulator → link → listener → Localisation) on each line, one figure per row beside its
target.

Along-track position error RMS with all sensors (≤ 1 m), its maximum through a 60 s GPS outage
(≤ 10 m), speed error RMS (≤ 0.2 km/h), position RMS with 20 % loss plus reordering (≤ 2 m),
odometer failure detection (≤ 1 s), and the IMU alone (no target).
"""

from __future__ import annotations

from dataclasses import dataclass

from deploy.bench.sfa_drive import DriveSettings
from deploy.bench.sfa_lockstep import run_lockstep
from onboard.plant.sensors import SensorFaults, TimeWindow
from onboard.sfa import LinkFaults, ListenerConfig
from trackdb import TrackMap, load_seed_line

__all__ = ["LINES", "AccuracyRow", "accuracy_rows"]

LINES = {"bologna-ring": 80.0, "milano-bologna": 300.0}
"""Cruise speed [km/h] of the bench drive on each line."""


@dataclass(frozen=True)
class AccuracyRow:
    line_id: str
    case: str
    figure: str
    value: float
    target: str
    ok: bool | None


def _drive(line_id: str, duration_s: float, **changes: object) -> DriveSettings:
    return DriveSettings(
        line_id=line_id,
        duration_s=duration_s,
        cruise_kmh=LINES[line_id],
        seed=8,
        **changes,  # type: ignore[arg-type]
    )


def accuracy_rows(durations_s: dict[str, float]) -> list[AccuracyRow]:
    """Every accuracy figure on every line, with ``durations_s[line]`` simulated seconds."""
    rows: list[AccuracyRow] = []
    for line_id, duration_s in durations_s.items():
        track_map = TrackMap(load_seed_line(line_id))
        rows += _nominal_rows(line_id, duration_s, track_map)
        rows.append(_gps_outage_row(line_id, duration_s, track_map))
        rows.append(_lossy_link_row(line_id, duration_s, track_map))
        rows += _odometer_failure_rows(line_id, duration_s, track_map)
        rows.append(_imu_alone_row(line_id, duration_s, track_map))
    return rows


def _nominal_rows(line_id: str, duration_s: float, track_map: TrackMap) -> list[AccuracyRow]:
    """Position and speed RMS with every sensor and a perfect link."""
    nominal = run_lockstep(_drive(line_id, duration_s), track_map).stats()
    return [
        AccuracyRow(
            line_id,
            "all sensors",
            "position RMS [m]",
            nominal.position_rms_m,
            "≤ 1",
            nominal.position_rms_m <= 1.0,
        ),
        AccuracyRow(
            line_id,
            "all sensors",
            "speed RMS [km/h]",
            nominal.speed_rms_kmh,
            "≤ 0.2",
            nominal.speed_rms_kmh <= 0.2,
        ),
    ]


def _gps_outage_row(line_id: str, duration_s: float, track_map: TrackMap) -> AccuracyRow:
    """The largest position error through a 60 s GPS outage half-way."""
    outage = TimeWindow(0.5 * duration_s, 0.5 * duration_s + 60.0)
    gps_out = run_lockstep(
        _drive(line_id, duration_s, sensor_faults=SensorFaults(gps_outages=(outage,))),
        track_map,
    ).stats(outage)
    return AccuracyRow(
        line_id,
        "60 s GPS outage",
        "position max in it [m]",
        gps_out.position_max_m,
        "≤ 10",
        gps_out.position_max_m <= 10.0,
    )


def _lossy_link_row(line_id: str, duration_s: float, track_map: TrackMap) -> AccuracyRow:
    """Position RMS with 20 % of the datagrams lost and 20 % reordered."""
    lossy = run_lockstep(
        _drive(line_id, duration_s, link_faults=LinkFaults(loss_rate=0.2, reorder_rate=0.2)),
        track_map,
    ).stats()
    return AccuracyRow(
        line_id,
        "20 % loss + reordering",
        "position RMS [m]",
        lossy.position_rms_m,
        "≤ 2",
        lossy.position_rms_m <= 2.0,
    )


def _odometer_failure_rows(
    line_id: str, duration_s: float, track_map: TrackMap
) -> list[AccuracyRow]:
    """How soon an odometer falling silent, or stuck at 0, half-way is reported failed."""
    rows: list[AccuracyRow] = []
    for mode, faults in (
        ("silent", SensorFaults(odometer_outages=(TimeWindow(0.5 * duration_s, 1e9),))),
        (
            "stuck at 0",
            SensorFaults(odometer_stuck_at_zero=(TimeWindow(0.5 * duration_s, 1e9),)),
        ),
    ):
        failed = run_lockstep(_drive(line_id, duration_s, sensor_faults=faults), track_map)
        delay = failed.detection_delay_s(0.5 * duration_s)
        rows.append(
            AccuracyRow(
                line_id,
                f"odometer {mode}",
                "detected after [s]",
                float("nan") if delay is None else delay,
                "≤ 1",
                delay is not None and delay <= 1.0,
            )
        )
    return rows


def _imu_alone_row(line_id: str, duration_s: float, track_map: TrackMap) -> AccuracyRow:
    """Position RMS on the IMU alone over at most 120 s: degraded, no target."""
    imu_only = run_lockstep(
        _drive(
            line_id, min(duration_s, 120.0), listener=ListenerConfig(sensors=frozenset({"imu"}))
        ),
        track_map,
    )
    return AccuracyRow(
        line_id,
        "IMU alone, 120 s",
        "position RMS [m]",
        imu_only.stats().position_rms_m,
        "degraded",
        None,
    )
