"""``ato sfa ...``: the sensor-fusion listener alone, the emulator, and the offline mode.

- ``ato sfa listen --input HOST:PORT --obcu HOST:PORT [--line LINE] [--track-dir DIR]``
  (CONTRACT.md §1): the listener on real sockets until a STOP packet (exit 0) or Ctrl-C. With
  ``--track-dir`` it reads the line from the onboard's verified copies (``ato onboard
  --track-dir``, any line the trackside holds), as the onboard it belongs to does; without it,
  from the built-in lines.
- ``ato sfa emulate --to HOST:PORT``: the interface-modules emulator sending an emulated drive.
- ``ato sfa record --out FILE``: an emulated drive in lockstep, its received datagrams with
  arrival times and the truth written to a recording (seed 002 §4.1.2).
- ``ato sfa replay FILE``: a recording through the filter with the sensors and noise chosen;
  error statistics against the recorded truth.
"""

from __future__ import annotations

import threading
from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer

if TYPE_CHECKING:
    from deploy.bench.sfa_drive import DriveSettings
    from trackdb import TrackMap

__all__ = ["sfa_app"]

sfa_app = typer.Typer(help="Sensor-fusion positioning (seed 002).", no_args_is_help=True)

LineOption = Annotated[str, typer.Option("--line", help="Line id.")]
SeedOption = Annotated[int, typer.Option("--seed", help="Seed of the emulator's randomness.")]


def _address(text: str) -> tuple[str, int]:
    from onboard.sfa import AddressError
    from onboard.sfa.sockets import parse_address

    try:
        return parse_address(text)
    except AddressError as exc:
        raise typer.BadParameter(str(exc)) from exc


def _track_map(line: str, track_dir: Path | None = None) -> TrackMap:
    """The built-in line ``line``, or the onboard's verified copy of it in ``track_dir``."""
    from onboard import TrackDataError
    from onboard.track_store import TrackDataStore
    from trackdb import TrackMap, load_seed_line

    if track_dir is None:
        try:
            return TrackMap(load_seed_line(line))
        except KeyError as exc:
            raise typer.BadParameter(f"{exc.args[0]} (or give --track-dir)") from exc
    try:
        stored = TrackDataStore(track_dir).load(line)
    except (TrackDataError, ValueError) as exc:
        raise typer.BadParameter(str(exc)) from exc
    if stored is None:
        raise typer.BadParameter(f"no copy of line {line!r} in {track_dir}")
    return TrackMap(stored)


@sfa_app.command()
def listen(
    input_address: Annotated[str, typer.Option("--input", help="HOST:PORT to receive INPUT on.")],
    obcu: Annotated[str, typer.Option("--obcu", help="HOST:PORT of the OBCU.")],
    line: LineOption = "bologna-ring",
    track_dir: Annotated[
        Path | None,
        typer.Option("--track-dir", help="The onboard's track data (ato onboard --track-dir)."),
    ] = None,
) -> None:
    """Run the sensor-fusion listener until STOP (exit 0)."""
    from deploy.processes import stop_on_signals
    from onboard.sfa import ListenerCore
    from onboard.sfa.sockets import ListenerRunner

    core = ListenerCore(_track_map(line, track_dir))
    stop = threading.Event()
    with (
        stop_on_signals(stop),
        ListenerRunner(
            core, input_address=_address(input_address), obcu_address=_address(obcu)
        ) as runner,
    ):
        host, port = runner.input_address
        typer.echo(f"listening on {host}:{port}, OBCU at {obcu}", err=True)
        status = runner.run(stop)
    counters = core.counters
    typer.echo(
        f"received {counters.received}, processed {dict(counters.processed)}, "
        f"dropped {dict(counters.dropped)}, outputs {counters.outputs_sent}, "
        f"acks {counters.acks_received}",
        err=True,
    )
    raise typer.Exit(code=status)


def _settings(
    line: str,
    duration: float,
    cruise_kmh: float,
    loss: float,
    reorder: float,
    seed: int,
    *,
    record: bool = False,
) -> DriveSettings:
    """The drive the options describe; bad options become ``typer.BadParameter``."""
    from deploy.bench.sfa_drive import DriveSettings
    from onboard.sfa import LinkFaults

    _track_map(line)
    if duration <= 0 or cruise_kmh <= 0:
        raise typer.BadParameter("--duration and --cruise-kmh must be positive")
    try:
        link_faults = LinkFaults(loss_rate=loss, reorder_rate=reorder)
    except ValueError as exc:
        raise typer.BadParameter(str(exc)) from exc
    return DriveSettings(
        line_id=line,
        duration_s=duration,
        cruise_kmh=cruise_kmh,
        seed=seed,
        link_faults=link_faults,
        record=record,
    )


@sfa_app.command()
def emulate(
    to: Annotated[str, typer.Option("--to", help="HOST:PORT of the listener.")],
    line: LineOption = "bologna-ring",
    duration: Annotated[float, typer.Option(help="Simulated drive [s].")] = 120.0,
    speed: Annotated[float, typer.Option(help="Simulated s per wall s (0: flat out).")] = 1.0,
    cruise_kmh: Annotated[float, typer.Option(help="Cruise speed [km/h].")] = 80.0,
    loss: Annotated[float, typer.Option(help="Datagram loss rate.")] = 0.0,
    reorder: Annotated[float, typer.Option(help="Datagram reorder rate.")] = 0.0,
    seed: SeedOption = 0,
) -> None:
    """Send an emulated drive's INPUT datagrams (GROUND_TRUTH … STOP) over UDP."""
    from deploy.bench.sfa_emulator import send_drive

    if speed < 0:
        raise typer.BadParameter("--speed must not be negative")
    settings = _settings(line, duration, cruise_kmh, loss, reorder, seed)
    sent = send_drive(settings, _track_map(line), _address(to), speed_factor=speed or float("inf"))
    typer.echo(f"sent {sent} datagrams")


@sfa_app.command()
def record(
    out: Annotated[Path, typer.Option("--out", help="Recording file (.npz).")],
    line: LineOption = "bologna-ring",
    duration: Annotated[float, typer.Option(help="Simulated drive [s].")] = 300.0,
    cruise_kmh: Annotated[float, typer.Option(help="Cruise speed [km/h].")] = 80.0,
    loss: Annotated[float, typer.Option(help="Datagram loss rate.")] = 0.0,
    reorder: Annotated[float, typer.Option(help="Datagram reorder rate.")] = 0.0,
    seed: SeedOption = 0,
) -> None:
    """Record an emulated drive's datagrams, arrival times and truth (lockstep)."""
    from deploy.bench.sfa_lockstep import run_lockstep
    from deploy.bench.sfa_recording import RecordingError

    result = run_lockstep(_settings(line, duration, cruise_kmh, loss, reorder, seed, record=True))
    if result.recording is None:
        raise typer.Exit(code=1)
    try:
        result.recording.save(out)
    except RecordingError as exc:
        typer.echo(str(exc), err=True)
        raise typer.Exit(code=1) from exc
    typer.echo(f"recorded {len(result.recording.datagrams)} datagrams to {out}")


@sfa_app.command()
def replay(
    file: Annotated[Path, typer.Argument(help="A recording made by `ato sfa record`.")],
    sensors: Annotated[
        str, typer.Option(help="Sensors enabled, comma-separated: imu,odometer,gps.")
    ] = "imu,odometer,gps",
    gps_sigma_m: Annotated[
        float | None, typer.Option(help="GPS σ along the track [m]; the filter's by default.")
    ] = None,
    acceleration_sigma: Annotated[
        float | None,
        typer.Option(help="IMU acceleration input σ [m/s²]; the filter's by default."),
    ] = None,
) -> None:
    """Replay a recording faster than real time; print errors against the truth."""
    from deploy.bench.sfa_recording import Recording, RecordingError
    from deploy.bench.sfa_recording import replay as run_replay
    from onboard.sfa import ALL_SENSORS, FilterConfig, ListenerConfig

    chosen = frozenset(name.strip() for name in sensors.split(",") if name.strip())
    if not chosen <= ALL_SENSORS:
        raise typer.BadParameter(f"unknown sensors {sorted(chosen - ALL_SENSORS)}")
    if any(sigma is not None and sigma <= 0 for sigma in (gps_sigma_m, acceleration_sigma)):
        raise typer.BadParameter("σ must be positive")
    # The node's filter unless told otherwise, so that a replay runs what the vehicle runs.
    defaults = FilterConfig()
    config = ListenerConfig(
        sensors=chosen,
        filter=FilterConfig(
            gps_sigma_m=defaults.gps_sigma_m if gps_sigma_m is None else gps_sigma_m,
            acceleration_noise_mps2=(
                defaults.acceleration_noise_mps2
                if acceleration_sigma is None
                else acceleration_sigma
            ),
        ),
    )
    try:
        result = run_replay(Recording.load(file), config)
    except (RecordingError, KeyError) as exc:
        typer.echo(f"cannot replay {file}: {exc}", err=True)
        raise typer.Exit(code=1) from exc
    typer.echo(
        f"sensors {','.join(sorted(chosen))}: {result.epochs_s.size} outputs, "
        f"position error RMS {result.position_rms_m:.3f} m, max {result.position_max_m:.3f} m, "
        f"speed error RMS {result.speed_rms_kmh:.3f} km/h"
    )
