"""An onboard process's metrics for a control room's Prometheus (docs/metrics.md).

:class:`OnboardCollector` reads a running :class:`~onboard.node.OnboardNode` when a scrape comes
(nothing is added to the executive's hot loop): the session and its losses, the messages
received and dropped per topic, the status reports, the Vital Control's interventions, the NMPC's
solves and their times, the positioning's health (the position's confidence interval, the fused
speed's age), the executive's overruns. Reading from the scrape's thread takes no lock: each
value is a counter or a field the node's thread replaces whole, and a scrape may see one cycle's
values mixed with the next one's, as any scrape of a live process does.

:func:`serve_metrics` serves them over HTTP on one port per process, on the loopback interface
by default, with TLS and client certificates of the deployment's CA when a PKI is given.
"""

from __future__ import annotations

import bisect
import ssl
import threading
from collections.abc import Iterator
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any
from wsgiref.simple_server import WSGIServer

from prometheus_client import CollectorRegistry, start_http_server
from prometheus_client.core import (
    CounterMetricFamily,
    GaugeMetricFamily,
    HistogramMetricFamily,
    Metric,
)
from prometheus_client.registry import Collector

from onboard.vc.ipc import VcEventKind
from protocol import TlsFiles

if TYPE_CHECKING:
    from onboard.node import OnboardNode

__all__ = ["NMPC_BUCKETS_S", "MetricsServer", "OnboardCollector", "serve_metrics"]

NMPC_BUCKETS_S = (0.001, 0.002, 0.005, 0.01, 0.02, 0.05, 0.1, 0.2, 0.5)
"""The NMPC solve time histogram's buckets [s]: the 20 ms bound of issue 18 falls on one."""


class _SolveTimes:
    """Cumulative bucket counts of the NMPC's solve times, taken from where the last scrape
    left the list (each solve counted once, a scrape costs only the new solves)."""

    def __init__(self) -> None:
        self.counts = [0] * (len(NMPC_BUCKETS_S) + 1)
        self.total_s = 0.0
        self.seen = 0

    def update(self, times_s: list[float]) -> None:
        end = len(times_s)
        for value in times_s[self.seen : end]:
            self.counts[bisect.bisect_left(NMPC_BUCKETS_S, value)] += 1
            self.total_s += value
        self.seen = end

    def buckets(self) -> list[tuple[str, float]]:
        cumulative, out = 0, []
        for bound, count in zip((*NMPC_BUCKETS_S, float("inf")), self.counts, strict=True):
            cumulative += count
            out.append(("+Inf" if bound == float("inf") else repr(bound), float(cumulative)))
        return out


class OnboardCollector(Collector):
    """The metrics of one onboard node, labelled with its vehicle id."""

    def __init__(self, node: OnboardNode) -> None:
        self._node = node
        self._vehicle = [node.vehicle_id]
        self._solve_times = _SolveTimes()
        self._lock = threading.Lock()

    def _gauge(self, name: str, documentation: str, value: float) -> GaugeMetricFamily:
        family = GaugeMetricFamily(name, documentation, labels=["vehicle"])
        family.add_metric(self._vehicle, value)
        return family

    def _counter(self, name: str, documentation: str, value: float) -> CounterMetricFamily:
        family = CounterMetricFamily(name, documentation, labels=["vehicle"])
        family.add_metric(self._vehicle, value)
        return family

    def collect(self) -> Iterator[Metric]:
        node = self._node
        yield self._gauge("ato_ob_up", "1 while the onboard process runs", 1.0)
        yield self._gauge(
            "ato_ob_sim_time_seconds", "The onboard's simulated time", node.clock.now_s
        )
        yield from self._session(node)
        yield from self._messages(node)
        yield from self._vital_control(node)
        yield from self._nmpc(node)
        yield from self._positioning(node)
        yield from self._executive(node)

    def _session(self, node: OnboardNode) -> Iterator[Metric]:
        client = node.session_client
        yield self._gauge(
            "ato_ob_session_established",
            "1 while a session with a trackside is open",
            float(client.established),
        )
        counters = client.counters
        for name, value in (
            ("accepted", counters.accepted),
            ("rejected", counters.rejected),
            ("lost", counters.lost),
        ):
            yield self._counter(f"ato_ob_sessions_{name}", f"Sessions {name}", value)
        yield self._gauge(
            "ato_ob_trackside_seen",
            "1 while a trackside's token is seen",
            float(node.trackside_seen),
        )

    def _messages(self, node: OnboardNode) -> Iterator[Metric]:
        received = CounterMetricFamily(
            "ato_ob_messages_received", "Messages received, by topic", labels=["vehicle", "topic"]
        )
        dropped = CounterMetricFamily(
            "ato_ob_messages_dropped",
            "Messages dropped, by topic and reason",
            labels=["vehicle", "topic", "reason"],
        )
        for subscriber in node.ports.subscribers():
            topic = [node.vehicle_id, subscriber.topic.name]
            stats = subscriber.stats
            received.add_metric(topic, stats.received)
            dropped.add_metric([*topic, "bad_payload"], stats.bad_payloads)
            dropped.add_metric([*topic, "queue_overflow"], stats.queue_overflows)
        yield received
        yield dropped
        yield self._counter("ato_ob_status_reports_sent", "Status reports sent", node.reports_sent)
        yield self._counter(
            "ato_ob_status_retransmissions", "Reports sent again", node.report_retransmissions
        )
        yield self._counter("ato_ob_commands_rejected", "Commands refused", node.commands_rejected)

    def _vital_control(self, node: OnboardNode) -> Iterator[Metric]:
        vital = node.stack.vital
        if vital is None:
            return
        events = vital.boards[0].vc.events
        interventions = CounterMetricFamily(
            "ato_ob_vc_events", "The Vital Control's events, by kind", labels=["vehicle", "kind"]
        )
        for kind in VcEventKind:
            count = sum(1 for event in events if event.kind is kind)
            interventions.add_metric([node.vehicle_id, kind.value], count)
        yield interventions
        yield self._gauge(
            "ato_ob_vc_eb_commanded", "1 while the VC commands the EB", float(vital.eb_commanded)
        )
        yield self._gauge(
            "ato_ob_vc_pair_tripped", "1 once the 2oo2 pair braked the train", float(vital.tripped)
        )

    def _nmpc(self, node: OnboardNode) -> Iterator[Metric]:
        stats = node.stack.driving.nmpc.stats
        with self._lock:  # two scrapes at once must not count a solve twice
            self._solve_times.update(stats.solve_times_s)
            buckets = self._solve_times.buckets()
            total_s = self._solve_times.total_s
        solve = HistogramMetricFamily(
            "ato_ob_nmpc_solve_seconds", "Wall time of the NMPC's solves", labels=["vehicle"]
        )
        solve.add_metric(self._vehicle, buckets, total_s)
        yield solve
        yield self._counter(
            "ato_ob_nmpc_failures", "Solves that fell back to the safe law", stats.failures
        )
        yield self._counter("ato_ob_nmpc_cold_starts", "Solves from a rollout", stats.cold_starts)

    def _positioning(self, node: OnboardNode) -> Iterator[Metric]:
        report = node.current_status()
        if report.position_confidence_m is not None:
            yield self._gauge(
                "ato_ob_position_confidence_m",
                "Positioning health: the position's confidence interval [m]",
                report.position_confidence_m,
            )
        yield self._gauge("ato_ob_speed_mps", "The estimated speed [m/s]", report.speed_mps)

    def _executive(self, node: OnboardNode) -> Iterator[Metric]:
        overruns = CounterMetricFamily(
            "ato_ob_task_overruns",
            "Releases whose body ended after the next release's wall deadline, by task",
            labels=["vehicle", "task"],
        )
        for name, stats in sorted(node.executive.stats.items()):
            overruns.add_metric([node.vehicle_id, name], stats.overruns)
        yield overruns


@dataclass
class MetricsServer:
    """A running metrics endpoint; :meth:`close` stops it."""

    server: WSGIServer
    thread: threading.Thread
    registry: CollectorRegistry

    @property
    def port(self) -> int:
        return int(self.server.server_address[1])

    def close(self) -> None:
        self.server.shutdown()
        self.server.server_close()
        self.thread.join(timeout=5.0)


def serve_metrics(
    collector: Collector, *, port: int, addr: str = "127.0.0.1", tls: TlsFiles | None = None
) -> MetricsServer:
    """Serve ``collector`` at ``http(s)://addr:port/metrics`` (``port=0``: a free port).

    With ``tls`` the endpoint is HTTPS and only clients with a certificate of ``tls.ca`` may
    scrape (the party's own files: a control room's Prometheus is given a certificate of the
    deployment's CA, docs/metrics.md)."""
    registry = CollectorRegistry(auto_describe=False)
    registry.register(collector)
    options: dict[str, Any] = {}
    if tls is not None:
        options = {
            "certfile": tls.certificate,
            "keyfile": tls.key,
            "client_cafile": tls.ca,
            "client_auth_required": True,
            "tls_min_version": ssl.TLSVersion.TLSv1_2,
        }
    server, thread = start_http_server(port, addr=addr, registry=registry, **options)
    return MetricsServer(server, thread, registry)
