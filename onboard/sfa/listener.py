"""The listener of seed 002 §3.1: INPUT_PROTOCOL in, the filter stepped, OUTPUT_PROTOCOL out.

:class:`ListenerCore` is the pure part: ``feed(datagram, arrival_s)`` takes one INPUT datagram
and returns the OUTPUT datagrams it produced; ``on_ack`` and ``poll`` do the rest. It opens no
socket and reads no clock, so it runs in lockstep and is replayed from recordings.
:mod:`onboard.sfa.sockets` drives it from real sockets.

Every datagram received is counted exactly once: processed (by sensor type), ignored before the
first GROUND_TRUTH, ignored because its sensor is disabled, dropped by reason, or still waiting
in the reorder buffer — :meth:`ListenerCounters.accounted` adds them up.

Time (CONTRACT.md §3): a sensor packet's epoch is the last STROBE timestamp plus k / rate, k
counting that sensor's packets since that STROBE, bounded from below under loss by the SEQ_NO
distance to it; a STROBE off schedule waits for the next to confirm it.
:class:`~onboard.sfa.time_base.SensorTimeBase` keeps that time base.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

from onboard.sfa.filter import FilterConfig, TrackKalmanFilter, check_fix
from onboard.sfa.reorder import ReorderBuffer
from onboard.sfa.status import (
    Health,
    ListenerCounters,
    SfaStatus,
    plausible,
)
from onboard.sfa.time_base import SensorTimeBase
from protocol import MalformedDatagramError
from protocol.udp import (
    SEQ_MODULO,
    InputPacket,
    OutputPacket,
    SensorType,
    decode_ack,
    decode_input,
    encode_output,
)
from trackdb import TrackMap

__all__ = [
    "ALL_SENSORS",
    "Health",
    "ListenerConfig",
    "ListenerCore",
    "ListenerCounters",
    "SfaStatus",
]

ALL_SENSORS = frozenset({"imu", "odometer", "gps"})
DEAD_IMU_ACCELERATION_SIGMA_MPS2 = 0.5
"""σ of the train's acceleration while the IMU is dead [m/s²], a white-noise density held for
``filter.UNKNOWN_INPUT_HOLD_S``: the URV brakes at up to 0.93 m/s² and accelerates at up to
about 1.8 m/s² (docs/sfa.md)."""
_SENSOR_NAMES = {SensorType.IMU: "imu", SensorType.ODOMETER: "odometer", SensorType.GPS: "gps"}
_MALFORMED_REASONS = {
    "TruncatedDatagramError": "truncated",
    "LengthMismatchError": "length_mismatch",
    "UnknownSensorTypeError": "unknown_type",
    "CountMismatchError": "count_mismatch",
}


@dataclass(frozen=True, kw_only=True)
class ListenerConfig:
    """Rates, timeouts and the filter's configuration (SI units).

    ``sensors`` chooses which sensors feed the filter (the offline configuration's switch);
    the others' packets are counted as ``disabled``.
    """

    imu_rate_hz: float = 100.0
    odometer_rate_hz: float = 20.0
    gps_rate_hz: float = 1.0
    output_period_s: float = 0.05
    odometer_silence_s: float = 0.5
    odometer_rejections: int = 5
    imu_silence_s: float = 0.2
    gps_silence_s: float = 3.0
    degraded_sigma_m: float = 10.0
    ack_timeout_s: float = 3.0
    reorder_depth: int = 16
    reorder_max_wait_s: float = 0.05
    sensors: frozenset[str] = ALL_SENSORS
    filter: FilterConfig = field(default_factory=FilterConfig)


class ListenerCore:
    """Decode, validate, reorder, filter, publish: one INPUT datagram at a time.

    Parameters
    ----------
    track_map : TrackMap
        The line the vehicle runs on.
    config : ListenerConfig
        Rates, timeouts and filter settings.
    on_output : callable, optional
        Called with the status behind each OUTPUT datagram as it is made (replay, telemetry).
    """

    def __init__(
        self,
        track_map: TrackMap,
        config: ListenerConfig | None = None,
        *,
        on_output: Callable[[SfaStatus], None] | None = None,
    ) -> None:
        self.on_output = on_output
        self.config = config or ListenerConfig()
        self.track_map = track_map
        self.filter = TrackKalmanFilter(track_map, self.config.filter)
        self.buffer: ReorderBuffer[InputPacket] = ReorderBuffer(
            depth=self.config.reorder_depth, max_wait_s=self.config.reorder_max_wait_s
        )
        self.counters = ListenerCounters()
        self._misplaced_counted = 0
        self.stopped = False
        self.status: SfaStatus | None = None
        self.time_base = SensorTimeBase(
            imu_rate_hz=self.config.imu_rate_hz,
            odometer_rate_hz=self.config.odometer_rate_hz,
            gps_rate_hz=self.config.gps_rate_hz,
            order_tolerance_s=self.config.reorder_max_wait_s,
        )
        # Bound once: called for every sensor packet.
        self._epoch = self.time_base.epoch
        self._output_seq = 0
        self._last_output_epoch_s = -math.inf
        self._last_seen_s: dict[str, float] = {}
        self._odometer_rejections = 0
        self._odometer_failed_at_s: float | None = None
        self._first_output_arrival_s: float | None = None
        self._last_ack_arrival_s: float | None = None
        self._now_s = 0.0
        self.last_ack_seq: int | None = None

    # -- input -----------------------------------------------------------------------------

    def feed(self, datagram: bytes, arrival_s: float) -> list[bytes]:
        """Take one INPUT datagram arrived at ``arrival_s`` [s]; returns OUTPUT datagrams."""
        self.counters.received += 1
        self._now_s = arrival_s
        try:
            packet = decode_input(datagram)
        except MalformedDatagramError as exc:
            self.counters.dropped[_MALFORMED_REASONS.get(type(exc).__name__, "malformed")] += 1
            return []
        if self.stopped:
            self.counters.dropped["after_stop"] += 1
            return []
        if not all(map(math.isfinite, packet.doubles)):
            self.counters.dropped["non_finite"] += 1
            return []
        if not plausible(packet, self.track_map.length_m):
            self.counters.dropped["invalid_value"] += 1
            return []
        buffer = self.buffer
        distance = buffer.distance(packet.seq_no)
        if (
            distance > buffer.window
            and packet.sensor_type in (SensorType.GROUND_TRUTH, SensorType.STOP)
            or distance < -1024
            and packet.sensor_type is SensorType.GROUND_TRUTH
        ):
            # A GROUND_TRUTH far from the order is a restarted sender, a STOP far ahead the
            # sender's last word: neither is late nor out of the reorder window (one corrupted
            # byte cannot make either from another type: their counts differ).
            outputs = self._release(buffer.reset(packet.seq_no))
        else:
            outputs = []
        refused = buffer.push(packet.seq_no, packet, arrival_s)
        if refused is not None:
            self.counters.dropped[refused] += 1
            return outputs
        outputs.extend(self._release(buffer.pop_ready(arrival_s)))
        return outputs

    def poll(self, now_s: float) -> list[bytes]:
        """Release what the reorder buffer holds past its wait; call when nothing arrives."""
        self._now_s = now_s
        return self._release(self.buffer.pop_ready(now_s))

    def stop(self) -> list[bytes]:
        """Flush the buffer (STOP, or the runner shutting down)."""
        outputs = self._release(self.buffer.flush())
        self.stopped = True
        return outputs

    def on_ack(self, datagram: bytes, arrival_s: float) -> None:
        """An ACK from the OBCU arrived at ``arrival_s`` [s]."""
        try:
            ack = decode_ack(datagram)
        except MalformedDatagramError:
            self.counters.acks_malformed += 1
            return
        self.counters.acks_received += 1
        self.last_ack_seq = ack.seq_no
        self._last_ack_arrival_s = arrival_s

    def filter_counters(self) -> dict[str, int]:
        """What the filter did with the measurements: IMU samples, odometer and GPS updates
        accepted and gated out (``*_rejected``; a GPS fix off the track counts there too), GPS
        fixes taken after a run of rejections (``gps_reanchored``), balise-group fixes
        (``fix_accepted``)."""
        flt = self.filter
        counters = {f"{name}_accepted": count for name, count in flt.accepted.items()}
        counters |= {f"{name}_rejected": count for name, count in flt.rejected.items()}
        counters["gps_reanchored"] = flt.reanchored
        return counters

    def link_lost(self, now_s: float) -> bool:
        """True when OUTPUT datagrams have gone out but no ACK came for ``ack_timeout_s``."""
        reference = self._last_ack_arrival_s
        if reference is None:
            reference = self._first_output_arrival_s
        return reference is not None and now_s - reference > self.config.ack_timeout_s

    # -- processing ------------------------------------------------------------------------

    def _count_misplaced(self) -> None:
        """Count as dropped the packets the reorder buffer refused on their turn."""
        misplaced = self.buffer.misplaced - self._misplaced_counted
        if misplaced:
            self.counters.dropped["misplaced"] += misplaced
            self._misplaced_counted = self.buffer.misplaced

    def _release(self, packets: list[InputPacket]) -> list[bytes]:
        self._count_misplaced()
        outputs: list[bytes] = []
        for packet in packets:
            if self.stopped:
                # Released in order, so these come after the STOP: the sender has finished.
                self.counters.dropped["after_stop"] += 1
                continue
            self._process(packet)
            outputs.extend(self._outputs_due(force=self.stopped))
        if self.stopped and len(self.buffer):
            self.counters.dropped["after_stop"] += len(self.buffer.flush())
            self._count_misplaced()
        return outputs

    def _process(self, packet: InputPacket) -> None:
        sensor_type = packet.sensor_type
        counters = self.counters
        if sensor_type is SensorType.STROBE:
            self._strobe(packet.doubles[0], packet.seq_no)
            return
        if sensor_type is SensorType.STOP:
            counters.processed["stop"] += 1
            self.stopped = True
            return
        if sensor_type is SensorType.GROUND_TRUTH:
            self._initialise(packet)
            counters.processed["ground_truth"] += 1
            return
        name = _SENSOR_NAMES[sensor_type]
        if not self.filter.initialised:
            counters.before_ground_truth += 1
            return
        epoch_s = self._epoch(sensor_type, packet.seq_no)
        if name not in self.config.sensors:
            counters.disabled += 1
            return
        if sensor_type is SensorType.IMU:
            # A sample gated out does not keep the IMU alive: it counts as not heard.
            if self.filter.imu(epoch_s, packet.doubles[0]):
                self._last_seen_s["imu"] = epoch_s
        elif sensor_type is SensorType.ODOMETER:
            speed_mps, sigma_mps = packet.doubles
            self._odometer(epoch_s, speed_mps, sigma_mps)
        else:
            latitude_deg, longitude_deg, _ = packet.doubles
            if self.filter.gps(epoch_s, latitude_deg, longitude_deg):
                self._last_seen_s["gps"] = epoch_s
        counters.processed[name] += 1
        self._update_status()

    def _strobe(self, strobe_s: float, seq_no: int) -> None:
        rebase = self.time_base.rebase_pending
        refused = self.time_base.strobe(strobe_s, seq_no)
        if refused is not None:
            self.counters.dropped[refused] += 1
            return
        if rebase and self.filter.initialised:
            # The first STROBE after a GROUND_TRUTH sets the time base of the new run.
            self.filter.epoch_s = strobe_s
            self._last_seen_s = {"imu": strobe_s, "odometer": strobe_s}
        self.counters.processed["strobe"] += 1

    def _initialise(self, packet: InputPacket) -> None:
        velocity_x, velocity_y, velocity_z, chainage_km = packet.doubles
        speed_mps = math.copysign(math.hypot(velocity_x, velocity_y, velocity_z), velocity_x)
        epoch_s = self.time_base.strobe_s
        self.filter.initialise(chainage_km * 1000.0, speed_mps, epoch_s)
        self.time_base.rebase()
        self._last_seen_s = {"imu": epoch_s, "odometer": epoch_s}
        self._odometer_rejections = 0
        self._odometer_failed_at_s = None
        self._last_output_epoch_s = -math.inf
        self._update_status()

    def _odometer(self, epoch_s: float, speed_mps: float, sigma_mps: float) -> None:
        if self.filter.odometer(epoch_s, speed_mps, sigma_mps):
            self._odometer_rejections = 0
            self._last_seen_s["odometer"] = epoch_s
        else:
            self._odometer_rejections += 1

    def _update_status(self) -> None:
        config, flt, seen = self.config, self.filter, self._last_seen_s
        epoch_s = flt.epoch_s
        imu_alive = epoch_s - seen.get("imu", -math.inf) <= config.imu_silence_s
        if not imu_alive:
            # A dead IMU must not leave its last acceleration integrating for ever; the speed is
            # then the odometer's, with the train's accelerations as the unknown input.
            flt.last_input_mps2 = float(flt.kf.x[2, 0])
        flt.unknown_input_sigma_mps2 = None if imu_alive else DEAD_IMU_ACCELERATION_SIGMA_MPS2
        odometer_alive = (
            epoch_s - seen.get("odometer", -math.inf) <= config.odometer_silence_s
            and self._odometer_rejections < config.odometer_rejections
        )
        if odometer_alive:
            self._odometer_failed_at_s = None
        elif self._odometer_failed_at_s is None:
            self._odometer_failed_at_s = epoch_s
        gps_alive = epoch_s - seen.get("gps", -math.inf) <= config.gps_silence_s
        # Read from the filter's arrays directly, not through its checked properties: this runs
        # for every datagram and the filter is initialised here (the same values).
        x = flt.kf.x
        sigma_m = math.sqrt(max(float(flt.kf.P[0, 0]), 0.0))
        if not imu_alive and not odometer_alive:
            health = Health.LOST
        elif not (imu_alive and odometer_alive) or sigma_m > config.degraded_sigma_m:
            health = Health.DEGRADED
        else:
            health = Health.OK
        self.status = SfaStatus(
            epoch_s=epoch_s,
            chainage_m=float(x[0, 0]),
            speed_mps=float(x[1, 0]),
            sigma_m=sigma_m,
            health=health,
            imu_alive=imu_alive,
            odometer_alive=odometer_alive,
            gps_alive=gps_alive,
            odometer_failed_at_s=self._odometer_failed_at_s,
        )

    def _outputs_due(self, *, force: bool = False) -> list[bytes]:
        flt = self.filter
        if not flt.initialised:
            return []
        if not force and flt.epoch_s < self._last_output_epoch_s + (
            self.config.output_period_s - 1e-9
        ):
            return []
        self._last_output_epoch_s = flt.epoch_s
        datagram = encode_output(
            OutputPacket(
                seq_no=self._output_seq,
                epoch_s=flt.epoch_s,
                arc_length_km=self.track_map.normalise(flt.chainage_m) / 1000.0,
            )
        )
        self._output_seq = (self._output_seq + 1) % SEQ_MODULO
        self.counters.outputs_sent += 1
        if self._first_output_arrival_s is None:
            self._first_output_arrival_s = self._now_s
        if self.on_output is not None and self.status is not None:
            self.on_output(self.status)
        return [datagram]

    # -- balise groups ---------------------------------------------------------------------

    def fix(self, chainage_m: float, sigma_m: float, epoch_s: float) -> None:
        """A balise-group fix (chainage on the line [m], σ [m], epoch [s]) into the filter.

        Raises
        ------
        ValueError
            If a value is not finite or σ is not positive.
        NotInitialisedError
            Before the first GROUND_TRUTH.
        """
        check_fix(chainage_m, sigma_m, epoch_s)
        self.filter.fix(chainage_m, sigma_m, epoch_s)
        self._update_status()
