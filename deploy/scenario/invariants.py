"""The invariants a whole-stack run must keep, judged on its KPIs (``kpis.json``: the truth).

Generated scenarios (``deploy.scenario.generate``) are judged by these rather than by
hand-written expectations: whatever the draw, the train never runs above the MRSP or the
journey's cap, never passes its end of authority, never meets an ETCS intervention, never meets
a VC emergency brake that no injected fault asks for, serves every stop of its journey within
the tolerance or has a documented reason not to, and its NMPC solves in bounded time. A run
that raised is a ``crash``. Each check is named; the thresholds come from the scenario's (or
the space's) :class:`~deploy.scenario.schema.InvariantSettings`.

=================  ============================================================================
invariant          violated when
=================  ============================================================================
overspeed_mrsp     ``max_overspeed_kmh`` > tolerance (the true speed above the MRSP, TSRs in)
overspeed_cap      ``max_speed_over_cap_kmh`` > tolerance (the true speed above the journey's
                   cap while in AD)
eoa_passed         ``min_eoa_margin_m`` < 0 (the true front end beyond ETCS's EoA)
eoa_stop_far       an ``eoa_stops`` item's ``distance_to_eoa_m`` > ``max_eoa_stop_m`` (the
                   train did not close up to an EoA it stood before)
etcs_intervention  ``etcs_sb_count`` or ``etcs_eb_count`` > 0
vc_eb              ``vc_eb_count`` > 0 and no fault of the scenario asks for it
                   (:func:`faults_asking_for_vc_eb`)
stop_missed        a stopping timing point of the journey not served within
                   ``max_stop_error_m``, without a documented reason (:func:`excused_stops`)
nmpc_unbounded     ``nmpc_fallback_s`` > ``nmpc_max_fallback_s``, or ``nmpc_ms.max`` >
                   ``nmpc_max_ms`` when that is set
crash              the run raised
=================  ============================================================================
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import get_args

from deploy.scenario.kpi_model import ExpectationResult, Kpis
from deploy.scenario.schema import (
    AtoFailure,
    InvariantName,
    InvariantSettings,
    RelayFault,
    ScenarioSpec,
    TachometerFault,
    VigilanceAbsent,
    ZenohLinkLoss,
)
from protocol import messages as m

__all__ = [
    "INVARIANTS",
    "Violation",
    "excused_stops",
    "faults_asking_for_vc_eb",
    "invariant_expectations",
    "judge",
]

INVARIANTS: tuple[InvariantName, ...] = get_args(InvariantName)
"""Every invariant, in the order of the summary's table."""
SESSION_RETURN_S = 2.0
"""The longest a new session takes once a lost Zenoh link is back (the link's 1 s lease, the
trackside's token seen again, the handshake), with a margin; an operator's answer is refused
until it stands (onboard.freshness)."""
INFEASIBLE_MARKS = ("infeasible", "minimum running time")
"""A refused journey whose reason says one of these was refused as timing-infeasible."""


@dataclass(frozen=True)
class Violation:
    invariant: InvariantName
    detail: str


def faults_asking_for_vc_eb(spec: ScenarioSpec, settings: InvariantSettings) -> list[str]:
    """The faults of ``spec`` after which a VC emergency brake is the right answer.

    An ATO-OB internal fault, a relay fault and a tachometer fault brake by design (the VC's
    catalogue). An absent operator and a lost Zenoh link (the operator sees nothing) ask for it
    when the operator may stay unseen at least ``vigilance_answer_s``, the vigilance timeout: a
    request made as the window opens is then missed. An absent operator is unseen for the
    window and his reaction. Over a lost link the answer the operator was about to give is
    lost with it (a request seen a reaction before the cut), so the link is unseen for the
    window, that reaction, the new session's handshake (:data:`SESSION_RETURN_S`) and a second
    reaction to the request still pending. Sensor, link, odometry, TSR and MA faults never do.
    """
    asking = []
    reaction_s = spec.operator.reaction_s
    for index, fault in enumerate(spec.faults):
        if isinstance(fault, AtoFailure | RelayFault | TachometerFault):
            asking.append(f"faults.{index} ({fault.kind})")
        elif isinstance(fault, VigilanceAbsent | ZenohLinkLoss):
            unseen_s = fault.end_s - fault.start_s + reaction_s
            if isinstance(fault, ZenohLinkLoss):
                unseen_s += reaction_s + SESSION_RETURN_S
            if unseen_s >= settings.vigilance_answer_s:
                asking.append(f"faults.{index} ({fault.kind}, {unseen_s:.1f} s unseen)")
    return asking


def _journey_refused_as_infeasible(kpis: Kpis) -> str | None:
    for action in kpis.actions or []:
        if action.action == "send_journey" and not action.accepted:
            detail = action.detail or ""
            if any(mark in detail for mark in INFEASIBLE_MARKS):
                return detail
    return None


def excused_stops(spec: ScenarioSpec, kpis: Kpis, settings: InvariantSettings) -> dict[str, str]:
    """The journey's stops that need not be served, each with its documented reason.

    A stop the vehicle reported (``journey_reports``: ``timing_infeasible`` or
    ``skipped_by_operator``); every stop of a journey refused before departure as
    timing-infeasible (by the trackside's check or the vehicle's planner); and the stops not
    served after a VC emergency brake that a fault asks for (the train stands in System Decay).
    """
    excused: dict[str, str] = {}
    for report in kpis.journey_reports or []:
        excused[report.stop] = report.reason
    if spec.journey is not None:
        refusal = _journey_refused_as_infeasible(kpis)
        if refusal is not None:
            for point in spec.journey.timing_points:
                excused.setdefault(point.id, f"journey refused as infeasible: {refusal[:120]}")
        if kpis.vc_eb_count > 0 and faults_asking_for_vc_eb(spec, settings):
            served = {stop.name for stop in kpis.stops}
            for point in spec.journey.timing_points:
                if point.id not in served:
                    excused.setdefault(point.id, "after a VC EB a fault asks for")
    return excused


def _overspeed_mrsp(_spec: ScenarioSpec, kpis: Kpis, settings: InvariantSettings) -> list[str]:
    over = kpis.max_overspeed_kmh
    tolerance = settings.overspeed_tolerance_kmh
    return [f"{over:.3f} km/h above the MRSP"] if over > tolerance else []


def _overspeed_cap(_spec: ScenarioSpec, kpis: Kpis, settings: InvariantSettings) -> list[str]:
    over = kpis.max_speed_over_cap_kmh or 0.0
    tolerance = settings.overspeed_tolerance_kmh
    return [f"{over:.3f} km/h above the journey's cap in AD"] if over > tolerance else []


def _eoa_passed(_spec: ScenarioSpec, kpis: Kpis, _settings: InvariantSettings) -> list[str]:
    margin = kpis.min_eoa_margin_m
    return [f"EoA passed by {-margin:.2f} m"] if margin is not None and margin < 0.0 else []


def _eoa_stop_far(_spec: ScenarioSpec, kpis: Kpis, settings: InvariantSettings) -> list[str]:
    return [
        f"stood {stop.distance_to_eoa_m:.2f} m before an EoA at {stop.time_s:.1f} s "
        f"(at most {settings.max_eoa_stop_m:g} m)"
        for stop in kpis.eoa_stops
        if stop.distance_to_eoa_m > settings.max_eoa_stop_m
    ]


def _etcs_intervention(_spec: ScenarioSpec, kpis: Kpis, _settings: InvariantSettings) -> list[str]:
    service, emergency = kpis.etcs_sb_count, kpis.etcs_eb_count
    if service or emergency:
        return [f"ETCS braked: {service} service, {emergency} emergency"]
    return []


def _vc_eb(spec: ScenarioSpec, kpis: Kpis, settings: InvariantSettings) -> list[str]:
    count = kpis.vc_eb_count
    if count == 0 or faults_asking_for_vc_eb(spec, settings):
        return []
    causes = ", ".join(item.cause for item in kpis.vc_interventions)
    return [f"{count} VC EB ({causes or 'cause unknown'}) and no fault asks for one"]


def _stop_missed(spec: ScenarioSpec, kpis: Kpis, settings: InvariantSettings) -> list[str]:
    if spec.journey is None:
        return []
    made = {stop.name: stop for stop in kpis.stops}
    excused = excused_stops(spec, kpis, settings)
    found = []
    for point in spec.journey.timing_points:
        if point.kind is not m.TimingPointKind.STOPPING or point.id in excused:
            continue
        stop = made.get(point.id)
        if stop is None:
            found.append(f"stop {point.id} not served")
        elif abs(stop.stop_error_m) > settings.max_stop_error_m:
            found.append(
                f"stop {point.id} {stop.stop_error_m:+.3f} m from its point "
                f"(tolerance {settings.max_stop_error_m} m)"
            )
    return found


def _nmpc_unbounded(_spec: ScenarioSpec, kpis: Kpis, settings: InvariantSettings) -> list[str]:
    found = []
    failures, fallback = kpis.nmpc_failures, kpis.nmpc_fallback_s
    if fallback > settings.nmpc_max_fallback_s:
        found.append(
            f"{failures} NMPC failures: {fallback:.1f} s on the fallback law "
            f"(bound {settings.nmpc_max_fallback_s:g} s)"
        )
    longest = None if kpis.nmpc_ms is None else kpis.nmpc_ms.max
    if longest is not None and settings.nmpc_max_ms is not None and longest > settings.nmpc_max_ms:
        found.append(f"NMPC solve of {longest:.1f} ms (bound {settings.nmpc_max_ms:g} ms)")
    return found


_CHECKS: dict[InvariantName, Callable[[ScenarioSpec, Kpis, InvariantSettings], list[str]]] = {
    "overspeed_mrsp": _overspeed_mrsp,
    "overspeed_cap": _overspeed_cap,
    "eoa_passed": _eoa_passed,
    "eoa_stop_far": _eoa_stop_far,
    "etcs_intervention": _etcs_intervention,
    "vc_eb": _vc_eb,
    "stop_missed": _stop_missed,
    "nmpc_unbounded": _nmpc_unbounded,
}


def judge(
    spec: ScenarioSpec,
    kpis: Kpis | None,
    *,
    settings: InvariantSettings | None = None,
    error: str | None = None,
) -> list[Violation]:
    """Every violation of the run of ``spec`` whose KPIs are ``kpis`` (None: it raised).

    The settings are ``settings``, else the scenario's ``[invariants]``, else the defaults;
    invariants named in their ``skip`` are not judged.
    """
    settings = settings or spec.invariants or InvariantSettings()
    if kpis is None:
        if "crash" in settings.skip:
            return []
        last = (error or "the run raised").strip().splitlines() or ["the run raised"]
        return [Violation("crash", last[-1])]
    return [
        Violation(name, detail)
        for name, check in _CHECKS.items()
        if name not in settings.skip
        for detail in check(spec, kpis, settings)
    ]


def invariant_expectations(spec: ScenarioSpec, kpis: Kpis) -> list[ExpectationResult]:
    """The invariants as ``kpis.json`` expectations: one entry per invariant judged."""
    settings = spec.invariants or InvariantSettings()
    violations = judge(spec, kpis, settings=settings)
    entries = []
    for name in _CHECKS:
        if name in settings.skip:
            continue
        found = [v.detail for v in violations if v.invariant == name]
        entries.append(
            ExpectationResult(
                name=f"invariant {name}", ok=not found, detail="; ".join(found) or "holds"
            )
        )
    return entries
