"""``ato bench sfa``: sensor-fusion accuracy, robustness and cost, each figure beside its target
(issue 8).

1. Accuracy, lockstep drives of the whole chain (emulator → link → listener → Localisation) on
   ``bologna-ring`` and ``milano-bologna``: along-track error RMS with all sensors (≤ 1 m), the
   maximum through a 60 s GPS outage (≤ 10 m), speed error RMS (≤ 0.2 km/h), RMS with 20 % loss
   plus reordering (≤ 2 m), odometer failure detection (≤ 1 s), and the IMU alone (no target);
   the drives are in :mod:`deploy.bench.sfa_accuracy`.
2. Fuzzing: random and mutated datagrams into a running listener core, and a share of them over
   UDP into a listener on sockets: no crash, every datagram counted.
3. Cost: decode + filter per IMU packet (median ≤ 50 µs, p99 printed) and listener throughput
   over real UDP on loopback (≥ 10 000 datagrams/s), plus the core's in-process rate.
"""

from __future__ import annotations

import multiprocessing
import socket
import struct
import threading
import time
from collections import Counter
from dataclasses import dataclass, field

import numpy as np
from rich.console import Console
from rich.markup import escape
from rich.table import Table

from deploy.bench.sfa_accuracy import AccuracyRow, accuracy_rows
from deploy.bench.sfa_drive import DriveSettings
from deploy.bench.sfa_lockstep import run_lockstep
from deploy.stats import percentiles
from onboard.sfa import ListenerCore
from onboard.sfa.sockets import ListenerRunner
from protocol.udp import SEQ_MODULO, InputPacket, SensorType, encode_input
from protocol.units import GRAVITY_MPS2
from trackdb import TrackMap, load_seed_line

__all__ = [
    "AccuracyRow",
    "FuzzResult",
    "accuracy_rows",
    "bench_sfa",
    "fuzz_datagrams",
    "fuzz_listener",
    "imu_cost_us",
    "udp_throughput",
]

# -- fuzzing ---------------------------------------------------------------------------------


_FUZZ_TYPES = (1, 2, 3, 8, 9, 10)
_FUZZ_WEIGHTS = (0.45, 0.15, 0.1, 0.08, 0.2, 0.02)
_FUZZ_COUNTS = {1: 6, 2: 2, 3: 3, 8: 4, 9: 1, 10: 0}
_FUZZ_CENTRES = {
    1: (0.0, 0.0, -GRAVITY_MPS2, 0.0, 0.0, 0.0),
    2: (20.0, 0.05),
    3: (44.515, 11.32, 42.0),
    8: (10.0, 0.0, 0.0, 1.0),
    9: (100.0,),
    10: (),
}


def _valid(rng: np.random.Generator, seq_no: int) -> bytes:
    """A well-formed packet near plausible values (sometimes far off), SEQ_NO near ``seq_no``
    or anywhere."""
    type_value = int(rng.choice(_FUZZ_TYPES, p=_FUZZ_WEIGHTS))
    centre = np.asarray(_FUZZ_CENTRES[type_value], dtype=float)
    spread = 1.0 if rng.random() < 0.8 else 1e4
    doubles = tuple(float(x) for x in centre + rng.normal(0.0, spread, size=centre.size))
    if rng.random() < 0.2:
        seq_no = int(rng.integers(SEQ_MODULO))
    return encode_input(InputPacket(SensorType(type_value), seq_no % SEQ_MODULO, doubles))


def _mutate(rng: np.random.Generator, datagram: bytes) -> bytes:
    data = bytearray(datagram)
    kind = int(rng.integers(6))
    if kind == 0 and data:
        data[int(rng.integers(len(data)))] = int(rng.integers(256))
    elif kind == 1:
        del data[int(rng.integers(len(data) + 1)) :]
    elif kind == 2:
        data.extend(rng.integers(0, 256, size=int(rng.integers(1, 16)), dtype=np.uint8).tobytes())
    elif kind == 3 and len(data) >= 5:
        data[3], data[4] = int(rng.integers(256)), int(rng.integers(256))
    elif kind == 4 and len(data) >= 13:
        special = float(rng.choice([np.nan, np.inf, -np.inf, 1e308, -0.0]))
        data[5:13] = struct.pack("<d", special)
    elif len(data) >= 3:
        data[1:3] = struct.pack("<H", int(rng.integers(SEQ_MODULO)))
    return bytes(data)


def fuzz_datagrams(rng: np.random.Generator, count: int) -> list[bytes]:
    """``count`` datagrams: a third random bytes, a third valid, a third mutated valid ones."""
    datagrams: list[bytes] = []
    for index in range(count):
        choice = index % 3
        if choice == 0:
            length = int(rng.integers(0, 90))
            datagrams.append(rng.integers(0, 256, size=length, dtype=np.uint8).tobytes())
        elif choice == 1:
            datagrams.append(_valid(rng, index // 3 + int(rng.integers(-3, 4))))
        else:
            datagrams.append(_mutate(rng, _valid(rng, index // 3)))
    return datagrams


@dataclass
class FuzzResult:
    """What the listeners fed with fuzz counted; a fuzzed STOP ends one and starts the next."""

    fed: int = 0
    received: int = 0
    accounted: int = 0
    listeners: int = 0
    dropped: Counter[str] = field(default_factory=Counter)
    processed: Counter[str] = field(default_factory=Counter)

    def add(self, core: ListenerCore) -> None:
        counters = core.counters
        self.listeners += 1
        self.received += counters.received
        self.accounted += counters.accounted(len(core.buffer))
        self.dropped.update(counters.dropped)
        self.processed.update(counters.processed)


def fuzz_listener(count: int, *, seed: int = 0) -> FuzzResult:
    """Feed ``count`` fuzz datagrams into listener cores; they must account for every one.

    Raises
    ------
    RuntimeError
        If the counters do not add up to the datagrams fed.
    """
    track_map = TrackMap(load_seed_line("bologna-ring"))
    result = FuzzResult()
    core = ListenerCore(track_map)
    rng = np.random.default_rng(seed)
    for index, datagram in enumerate(fuzz_datagrams(rng, count)):
        core.feed(datagram, index * 1e-3)
        result.fed += 1
        if core.stopped:
            result.add(core)
            core = ListenerCore(track_map)
    result.add(core)
    if not result.fed == result.received == result.accounted:
        raise RuntimeError(f"fuzz: counters do not add up: {result}")
    return result


# -- cost ------------------------------------------------------------------------------------


def imu_cost_us(count: int) -> tuple[float, float]:
    """Median and p99 [µs] of ``feed`` for one IMU datagram (decode, reorder, filter, output)."""
    core = ListenerCore(TrackMap(load_seed_line("bologna-ring")))
    core.feed(encode_input(InputPacket(SensorType.GROUND_TRUTH, 0, (10.0, 0, 0, 0.1))), 0.0)
    rng = np.random.default_rng(1)
    accelerations = rng.normal(0.0, 0.1, size=count)
    datagrams = [
        encode_input(
            InputPacket(
                SensorType.IMU,
                (index + 1) % SEQ_MODULO,
                (float(a), 0.0, -GRAVITY_MPS2, 0.0, 0.0, 0.0),
            )
        )
        for index, a in enumerate(accelerations)
    ]
    samples = np.empty(count)
    clock = time.perf_counter_ns
    for index, datagram in enumerate(datagrams):
        started = clock()
        core.feed(datagram, index * 0.01)
        samples[index] = clock() - started
    median_ns, p99_ns = percentiles(samples, (50, 99))
    return median_ns / 1e3, p99_ns / 1e3


def _send_datagrams(datagrams: list[bytes], address: tuple[str, int]) -> None:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
        pause = threading.Event()
        for index, datagram in enumerate(datagrams):
            sock.sendto(datagram, address)
            if index % 200 == 199:
                pause.wait(0.002)


def udp_throughput(seconds_of_drive: float) -> tuple[int, int, float, float]:
    """A recorded drive's datagrams sent flat out from another process to a listener on
    loopback: (sent, processed by the listener, datagrams/s over UDP, datagrams/s in-process)."""
    recording = run_lockstep(
        DriveSettings(duration_s=seconds_of_drive, seed=3, record=True)
    ).recording
    if recording is None:
        raise RuntimeError("no recording")
    datagrams = recording.datagrams
    track_map = TrackMap(load_seed_line("bologna-ring"))
    core = ListenerCore(track_map)
    started = time.perf_counter()
    for index, datagram in enumerate(datagrams):
        core.feed(datagram, index * 1e-4)
    in_process = len(datagrams) / (time.perf_counter() - started)

    core = ListenerCore(track_map)
    with ListenerRunner(
        core, input_address=("127.0.0.1", 0), obcu_address=("127.0.0.1", 9)
    ) as runner:
        sender = multiprocessing.get_context("spawn").Process(
            target=_send_datagrams, args=(datagrams, runner.input_address)
        )
        sender.start()
        while core.counters.received == 0:
            runner.poll_once(0.5)
        first_s = time.perf_counter()
        last_s, idle = first_s, 0
        while not core.stopped and idle < 20:
            before = core.counters.received
            runner.poll_once(0.05)
            if core.counters.received == before:
                idle += 1
            else:
                idle, last_s = 0, time.perf_counter()
        sender.join(timeout=10.0)
    rate = core.counters.received / max(last_s - first_s, 1e-9)
    return len(datagrams), core.counters.received, rate, in_process


# -- report ----------------------------------------------------------------------------------


def _mark(ok: bool | None) -> str:
    return "" if ok is None else ("ok" if ok else "MISSED")


def bench_sfa(
    *,
    ring_s: float = 900.0,
    milano_s: float = 2700.0,
    fuzz_count: int = 100_000,
    imu_count: int = 20_000,
    throughput_drive_s: float = 300.0,
) -> dict[str, object]:
    """Run everything, print the tables, return the figures."""
    console = Console(width=120)
    rows = accuracy_rows({"bologna-ring": ring_s, "milano-bologna": milano_s})
    table = Table(title="SFA accuracy, lockstep drives (Localisation estimate vs truth, 10 ms)")
    for column in ("line", "case", "figure", "value", "target", ""):
        table.add_column(column, justify="right" if column == "value" else "left")
    for row in rows:
        table.add_row(
            row.line_id, row.case, escape(row.figure), f"{row.value:.3f}", row.target, _mark(row.ok)
        )
    console.print(table)

    fuzz = fuzz_listener(fuzz_count)
    console.print(
        f"fuzz: {fuzz.fed} datagrams fed, {fuzz.received} received, {fuzz.accounted} accounted "
        f"(target: all), over {fuzz.listeners} listeners (a fuzzed STOP ends one); "
        f"dropped {dict(sorted(fuzz.dropped.items()))}, "
        f"processed {dict(sorted(fuzz.processed.items()))}"
    )
    median_us, p99_us = imu_cost_us(imu_count)
    sent, received, udp_rate, core_rate = udp_throughput(throughput_drive_s)
    cost = Table(title="SFA cost")
    for column in ("figure", "value", "target", ""):
        cost.add_column(column, justify="right" if column == "value" else "left")
    cost.add_row(
        escape("decode + filter per IMU packet, median [µs]"),
        f"{median_us:.1f}",
        "≤ 50",
        _mark(median_us <= 50.0),
    )
    cost.add_row(escape("decode + filter per IMU packet, p99 [µs]"), f"{p99_us:.1f}", "", "")
    cost.add_row(
        escape("listener throughput over UDP [datagrams/s]"),
        f"{udp_rate:.0f}",
        "≥ 10000",
        _mark(udp_rate >= 10_000),
    )
    cost.add_row("  datagrams sent / received", f"{sent} / {received}", "", "")
    cost.add_row(escape("listener core in-process [datagrams/s]"), f"{core_rate:.0f}", "", "")
    console.print(cost)
    return {
        "accuracy": rows,
        "fuzz": fuzz,
        "imu_median_us": median_us,
        "imu_p99_us": p99_us,
        "udp_datagrams_per_s": udp_rate,
        "core_datagrams_per_s": core_rate,
    }
