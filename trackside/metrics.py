"""Metrics a control room scrapes: ``GET /metrics`` in Prometheus's text format (docs/metrics.md).

Everything but the REST latency is read when the scrape comes, from what the service already
keeps (the bridge's fleet and counters, the session manager's, the recorder's), so nothing on the
hot paths changes; the REST latency is a histogram the :class:`RestLatencyMiddleware` fills, by
method, route template (not the raw path, whose ids would make a series per vehicle or user) and
status class.

Each app has its own :class:`~prometheus_client.CollectorRegistry`, so that several services in
one process (the tests') do not share series. Access: with ``metrics_token`` set, a bearer token
equal to it; without, only clients on the loopback interface (a Prometheus on another machine is
given the token).
"""

from __future__ import annotations

import hmac
import time
from collections.abc import Callable, Iterator
from typing import Any

from fastapi import FastAPI, Request, Response
from prometheus_client import CollectorRegistry, Histogram
from prometheus_client.core import CounterMetricFamily, GaugeMetricFamily, Metric
from prometheus_client.exposition import CONTENT_TYPE_LATEST, generate_latest
from prometheus_client.registry import Collector
from starlette.types import ASGIApp, Message, Receive, Scope, Send

__all__ = [
    "LOOPBACK_HOSTS",
    "RestLatencyMiddleware",
    "add_metrics",
    "planner_metrics",
    "route_template",
]

LOOPBACK_HOSTS = frozenset({"127.0.0.1", "::1", "localhost"})
"""Clients allowed to scrape when no token is set."""

REST_BUCKETS_S = (0.001, 0.0025, 0.005, 0.01, 0.025, 0.05, 0.1, 0.25, 0.5, 1.0, 2.5, 10.0)
"""The REST latency histogram's buckets [s]: the 50 ms target of issue 23 falls on one."""


class RestLatencyMiddleware:
    """Times every HTTP request into ``histogram`` (ASGI, around the whole app)."""

    def __init__(self, app: ASGIApp, histogram: Histogram) -> None:
        self.app = app
        self.histogram = histogram

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        started = time.perf_counter()
        status = [500]

        async def sending(message: Message) -> None:
            if message["type"] == "http.response.start":
                status[0] = int(message["status"])
            await send(message)

        try:
            await self.app(scope, receive, sending)
        finally:
            self.histogram.labels(
                method=scope.get("method", ""),
                route=route_template(scope),
                status=f"{status[0] // 100}xx",
            ).observe(time.perf_counter() - started)


def route_template(scope: Scope) -> str:
    """The request's path with each path parameter's value put back as ``{name}``, when a
    route matched; ``unmatched`` otherwise (a scan of random paths makes no new series).

    Read from the path and the parameters, not from the matched route's ``path``: a route of a
    router included in another one holds only its part of the path."""
    if scope.get("route") is None:
        return "unmatched"
    names = {str(value): name for name, value in scope.get("path_params", {}).items()}
    segments = str(scope.get("path", "")).split("/")
    return "/".join(f"{{{names[part]}}}" if part in names else part for part in segments)


class _ServiceCollector(Collector):
    """The fleet, the sessions, the messages and the recorder, read at each scrape."""

    def __init__(self, state: Any) -> None:
        self._state = state

    def collect(self) -> Iterator[Metric]:
        bridge = getattr(self._state, "bridge", None)
        if bridge is not None:
            yield from _fleet_metrics(bridge)
            yield from _session_metrics(bridge.sessions)
            yield from _message_metrics(bridge)
        recorder = getattr(self._state, "recorder", None)
        if recorder is not None:
            yield from _recorder_metrics(recorder.stats)
        planner = getattr(getattr(self._state, "commands", None), "planner", None)
        if planner is not None:
            yield from planner_metrics(planner.stats)


def _fleet_metrics(bridge: Any) -> Iterator[Metric]:
    fleet = bridge.fleet()
    alive = GaugeMetricFamily(
        "ato_ts_vehicle_alive", "1 while the vehicle's token is alive", labels=["vehicle"]
    )
    age = GaugeMetricFamily(
        "ato_ts_vehicle_status_age_seconds", "Wall time since its last status", labels=["vehicle"]
    )
    rate_ok = GaugeMetricFamily(
        "ato_ts_vehicle_status_rate_ok",
        "1 while its status arrives at the expected rate",
        labels=["vehicle"],
    )
    confidence = GaugeMetricFamily(
        "ato_ts_vehicle_position_confidence_m",
        "Positioning health: the onboard's position confidence interval [m]",
        labels=["vehicle"],
    )
    eb = GaugeMetricFamily(
        "ato_ts_vehicle_eb_commanded",
        "1 while the Vital Control's EB is commanded",
        labels=["vehicle"],
    )
    for snapshot in fleet:
        vehicle = [snapshot.id]
        alive.add_metric(vehicle, float(snapshot.alive))
        rate_ok.add_metric(vehicle, float(snapshot.status_rate_ok))
        if snapshot.status_age_s is not None:
            age.add_metric(vehicle, snapshot.status_age_s)
        status = snapshot.status
        if status is not None and status.position_confidence_m is not None:
            confidence.add_metric(vehicle, status.position_confidence_m)
        if status is not None and status.vital_control is not None:
            eb.add_metric(vehicle, float(status.vital_control.eb_commanded))
    yield GaugeMetricFamily("ato_ts_vehicles_known", "Vehicles seen", value=len(fleet))
    yield GaugeMetricFamily(
        "ato_ts_vehicles_alive", "Vehicles alive", value=sum(s.alive for s in fleet)
    )
    yield from (alive, age, rate_ok, confidence, eb)


def _session_metrics(sessions: Any) -> Iterator[Metric]:
    yield GaugeMetricFamily("ato_ts_sessions_open", "Sessions open", value=len(sessions.sessions))
    yield CounterMetricFamily(
        "ato_ts_sessions_lost", "Sessions lost (timeout or token gone)", value=sessions.lost
    )
    yield CounterMetricFamily(
        "ato_ts_sessions_rejected", "Handshakes refused", value=sessions.rejected
    )
    yield CounterMetricFamily(
        "ato_ts_status_reports_stale",
        "Reports older than the last one",
        value=sessions.stale_reports,
    )
    yield CounterMetricFamily(
        "ato_ts_status_reports_outside_session",
        "Reports with no session open",
        value=sessions.reports_outside_session,
    )


def _message_metrics(bridge: Any) -> Iterator[Metric]:
    received = CounterMetricFamily(
        "ato_ts_messages_received", "Zenoh messages received, by topic", labels=["topic"]
    )
    dropped = CounterMetricFamily(
        "ato_ts_messages_dropped",
        "Zenoh messages dropped, by topic and reason (bad payload, queue overflow)",
        labels=["topic", "reason"],
    )
    for topic, stats in sorted(bridge.topic_stats().items()):
        received.add_metric([topic], stats.received)
        dropped.add_metric([topic, "bad_payload"], stats.bad_payloads)
        dropped.add_metric([topic, "queue_overflow"], stats.queue_overflows)
    yield received
    yield dropped
    yield CounterMetricFamily(
        "ato_ts_bad_liveliness_tokens",
        "Liveliness tokens not naming a vehicle",
        value=bridge.bad_liveliness,
    )


def _recorder_metrics(stats: Any) -> Iterator[Metric]:
    written = CounterMetricFamily(
        "ato_ts_recorder_rows", "Status and event rows, by outcome", labels=["outcome"]
    )
    written.add_metric(["queued"], stats.queued)
    written.add_metric(["written"], stats.written)
    written.add_metric(["dropped"], stats.dropped)
    yield written
    yield CounterMetricFamily(
        "ato_ts_recorder_failed_batches", "Batches the database refused", value=stats.failed_batches
    )


def planner_metrics(stats: Any) -> Iterator[Metric]:
    """The journey planner's outcomes (``trackside.journey_planner.PlannerStats``)."""
    planned = CounterMetricFamily(
        "ato_ts_journeys_planned",
        "Journeys planned against the other trains', by outcome",
        labels=["outcome"],
    )
    planned.add_metric(["as_stored"], stats.as_stored)
    planned.add_metric(["delayed"], stats.delayed)
    planned.add_metric(["refused"], stats.refused)
    yield planned
    yield CounterMetricFamily(
        "ato_ts_journey_delay_seconds",
        "Delays the planner gave journeys, summed",
        value=stats.delay_s,
    )


def _allowed(request: Request, token: str | None) -> bool:
    if token is None:
        host = request.client.host if request.client else ""
        return host in LOOPBACK_HOSTS
    given = request.headers.get("authorization", "")
    scheme, _, credentials = given.partition(" ")
    return scheme.lower() == "bearer" and hmac.compare_digest(credentials.encode(), token.encode())


def add_metrics(app: FastAPI, *, token: Callable[[], str | None]) -> CollectorRegistry:
    """The app's registry, its REST latency middleware and its ``GET /metrics`` route;
    ``token`` gives the scrape token (None: loopback clients only)."""
    registry = CollectorRegistry(auto_describe=True)
    histogram = Histogram(
        "ato_ts_rest_request_seconds",
        "REST request latency, by method, route template and status class",
        ["method", "route", "status"],
        buckets=REST_BUCKETS_S,
        registry=registry,
    )
    registry.register(_ServiceCollector(app.state))
    app.add_middleware(RestLatencyMiddleware, histogram=histogram)
    app.state.metrics_registry = registry

    @app.get("/metrics", include_in_schema=False)
    def metrics(request: Request) -> Response:
        """Prometheus's text format (the token, or loopback only)."""
        if not _allowed(request, token()):
            return Response(
                status_code=403, content="metrics: forbidden\n", media_type="text/plain"
            )
        return Response(generate_latest(registry), media_type=CONTENT_TYPE_LATEST)

    return registry
