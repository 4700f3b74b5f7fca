"""AtoObController: the ATO-OB state machine (SUBSET-125 §9; DOMAIN.md §2.1), called with the time.

Each cycle, :meth:`AtoObController.step` takes the time and an :class:`AtoObInputs`, works out
which triggers of :data:`~onboard.ato_ob.transitions.ATO_OB_TRANSITIONS` hold, takes at most one
transition, and returns an :class:`AtoObOutput`: the state, the mode the ADF's supervisory
controller should be in, the traction permission, the full service brake, the AD request to ETCS,
the session-loss fallback and the ETCS limits the ADF must respect.

The operator's requests are calls taking effect at once: :meth:`~AtoObController.engage` (the
remote driver's "ATO Engage", RE only), :meth:`~AtoObController.disengage` and
:meth:`~AtoObController.reset` (FA only, once the cause has cleared). A refused request raises
:class:`~onboard.ato_ob.RequestRefusedError` with the reason; an accepted one updates
:attr:`~AtoObController.output` at once, from the last cycle's inputs.

GoA4 choices (docs/ato_ob.md):

- after a nominal stop at a stopping point (EG → AV, the holding brake applied) the unmanned
  train re-engages by itself once the engagement conditions hold again (dwell elapsed, MA,
  session): AV → RE → EG without a driver; the remote driver's engage is needed only to start a
  journey, after a disengage, a fallback stop or a fault;
- a lost trackside session while engaged does not disengage: the train runs on to the next
  stopping point and stops there (:attr:`AtoObOutput.stop_at_next_stopping_point`), then waits
  in AV for the session and the remote driver; a session back before that stop (a trackside
  restart, a short link outage) cancels the fallback and the journey goes on;
- after the 5 s of DE, and in FA, the ATO-OB commands the full service brake: there is no driver
  on board to take over. It never commands the EB (DOMAIN.md §2.1).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from onboard.adf.supervisor import ModeRequest
from onboard.ato_ob._exceptions import AtoObInputError, RequestRefusedError
from onboard.ato_ob.conditions import (
    AtoObInputs,
    Condition,
    EtcsStatus,
    failed_configuration_conditions,
    failed_engagement_conditions,
    failed_operational_conditions,
)
from onboard.ato_ob.transitions import TransitionRule, Trigger, select_rule
from protocol.messages import AtoState, EtcsMode

__all__ = [
    "AUTOMATIC_DRIVING_ENTRY_S",
    "DISENGAGING_S",
    "ETCS_LINK_TIMEOUT_S",
    "FAILURE_WARNING_S",
    "AtoObController",
    "AtoObOutput",
    "AtoTransition",
]

DISENGAGING_S = 5.0
"""How long DE follows the profile without traction before the full service brake [s] (§2.1)."""
FAILURE_WARNING_S = 5.0
"""How long the failure warning sounds on entering FA [s] (§2.1)."""
ETCS_LINK_TIMEOUT_S = 1.0
"""No ETCS-OB output for longer than this is a lost link [s]. ⚠ Not from SUBSET-130: a default."""
AUTOMATIC_DRIVING_ENTRY_S = 2.0
"""Once engaged, ETCS must be in AD within this time [s]. ⚠ Not from the standards: a default."""

_S = AtoState
_DRIVER_STATES = frozenset({_S.NOT_AVAILABLE, _S.AVAILABLE, _S.READY})
"""States in which the remote driver may drive (RD)."""


@dataclass(frozen=True, kw_only=True)
class AtoTransition:
    """A transition taken: when, from, to, by which trigger, and why in words."""

    time_s: float
    source: AtoState
    target: AtoState
    trigger: Trigger
    reason: str


@dataclass(frozen=True, kw_only=True)
class AtoObOutput:
    """One cycle's outcome of :meth:`AtoObController.step`."""

    time_s: float
    state: AtoState
    mode_request: ModeRequest
    """What the ADF's supervisory controller should do; OFF holds the vehicle."""
    automatic_driving_requested: bool
    """Ask ETCS for AD (FS → AD [80]); False drops it (AD → FS [33]/[53])."""
    traction_allowed: bool
    full_service_brake: bool
    """The ATO-OB commands the full service brake; it never commands the EB."""
    stop_at_next_stopping_point: bool
    """Session lost while engaged: the ADF stops at the next stopping point (GoA4 fallback)."""
    continue_after_dwell: bool
    """After this stop the train re-engages by itself once the dwell has elapsed (GoA4)."""
    failure_warning: bool
    """The failure warning for the operator, for 5 s after entering FA."""
    disengaging_remaining_s: float | None
    """In DE: time left before the full service brake [s], 0 once it is applied."""
    unavailable_reasons: tuple[Condition, ...]
    """Why not available: the failed configuration (CO), fault (FA) or operational conditions."""
    not_ready_reasons: tuple[Condition, ...]
    """Why not ready: the failed engagement conditions."""
    permitted_speed_mps: float
    """ETCS's permitted speed for the ADF [m/s]; 0 before any ETCS-OB output."""
    end_of_authority_distance_m: float | None
    """ETCS's distance to the EoA for the ADF [m]."""
    supervised_location_distance_m: float | None
    """ETCS's distance to the SvL for the ADF [m]."""


class AtoObController:
    """The ATO-OB controller of one vehicle.

    Parameters
    ----------
    start_s : float
        The time [s] at power-up; every call's ``now_s`` must not go back from the last.
    disengaging_s, failure_warning_s, etcs_link_timeout_s, automatic_driving_entry_s : float
        The timers [s]; see the module's constants.
    """

    def __init__(
        self,
        *,
        start_s: float = 0.0,
        disengaging_s: float = DISENGAGING_S,
        failure_warning_s: float = FAILURE_WARNING_S,
        etcs_link_timeout_s: float = ETCS_LINK_TIMEOUT_S,
        automatic_driving_entry_s: float = AUTOMATIC_DRIVING_ENTRY_S,
    ) -> None:
        timers = (disengaging_s, failure_warning_s, etcs_link_timeout_s, automatic_driving_entry_s)
        if not all(math.isfinite(t) and t > 0.0 for t in timers):
            raise AtoObInputError("the timers need positive finite durations")
        if not math.isfinite(start_s):
            raise AtoObInputError("the start time must be finite")
        self.disengaging_s = disengaging_s
        self.failure_warning_s = failure_warning_s
        self.etcs_link_timeout_s = etcs_link_timeout_s
        self.automatic_driving_entry_s = automatic_driving_entry_s
        self.state = _S.NP
        self.transitions: list[AtoTransition] = []
        self._time_s = start_s
        self._entered_s = start_s
        self._link_reference_s = start_s
        """Since when the link is supervised while no ETCS-OB output has come yet."""
        self._etcs: EtcsStatus | None = None
        self._inputs: AtoObInputs | None = None
        self._automatic_driving_seen = False
        """ETCS has been in AD since the ATO-OB entered EG."""
        self._moved_since_engaged = False
        self._fallback_stop = False
        self._continue_after_dwell = False
        self.output = self._output(start_s)

    # -- cycle ----------------------------------------------------------------------------------

    def step(self, now_s: float, inputs: AtoObInputs) -> AtoObOutput:
        """Run one cycle at ``now_s`` [s]: at most one transition, then the outputs."""
        self._check_time(now_s)
        if inputs.etcs is not None:
            if inputs.etcs.received_s > now_s:
                raise AtoObInputError("an ETCS-OB output received after now")
            self._etcs = inputs.etcs
        self._inputs = inputs
        if self.state is _S.ENGAGED:
            self._automatic_driving_seen |= (
                self._etcs is not None and self._etcs.mode is EtcsMode.AD
            )
            self._moved_since_engaged |= not inputs.standstill
            if not inputs.trackside_session_alive:
                self._fallback_stop = True
            elif not inputs.standstill:
                # The session is back before the stop: the journey goes on as planned.
                self._fallback_stop = False
        if inputs.remote_driving_selected:
            # The remote driver has taken the vehicle: it must not drive off on its own.
            self._continue_after_dwell = False
        triggers = self._triggers(now_s, inputs)
        rule = select_rule(self.state, triggers.keys())
        if rule is not None:
            self._enter(rule, now_s, triggers[rule.trigger])
        self.output = self._output(now_s)
        return self.output

    def _triggers(self, now_s: float, inputs: AtoObInputs) -> dict[Trigger, str]:
        """The triggers that hold now, each with the reason recorded if its row is taken."""
        if self.state is _S.NP:
            return {Trigger.POWER_ON: "powered up"}
        found: dict[Trigger, str] = {}
        if not self._link_alive(now_s):
            found[Trigger.ETCS_LINK_LOST] = (
                f"no ETCS-OB output for more than {self.etcs_link_timeout_s} s"
            )
        if inputs.internal_fault:
            found[Trigger.INTERNAL_FAULT] = "internal fault reported"
        if not self._configuration_failures(now_s, inputs):
            found[Trigger.CONFIGURED] = "configuration complete"
        operational = self._operational_failures(now_s, inputs)
        if operational:
            found[Trigger.NOT_OPERATIONAL] = "lost: " + ", ".join(operational)
        else:
            found[Trigger.OPERATIONAL] = "operational conditions hold"
        engagement = failed_engagement_conditions(inputs)
        if engagement:
            found[Trigger.NOT_ENGAGEABLE] = "lost: " + ", ".join(engagement)
        else:
            found[Trigger.ENGAGEABLE] = "engagement conditions hold"
        if self._continue_after_dwell:
            found[Trigger.AUTOMATIC_REENGAGEMENT] = "dwell elapsed: the journey continues"
        if inputs.standstill and inputs.end_of_journey_reached:
            found[Trigger.END_OF_JOURNEY] = "stopped at the End of Journey"
        if inputs.standstill and inputs.at_stopping_point and self._moved_since_engaged:
            if self._fallback_stop:
                found[Trigger.FALLBACK_STOP_COMPLETED] = (
                    "trackside session lost: stopped at the stopping point"
                )
            found[Trigger.STOPPED_AT_STOPPING_POINT] = "stopped at a stopping point"
        if self.state is _S.DISENGAGING:
            if now_s - self._entered_s < self.disengaging_s and not operational:
                found[Trigger.CONDITIONS_RECOVERED] = "operational conditions hold again"
            if self._disengaging_expired(now_s) and inputs.standstill:
                found[Trigger.BRAKED_TO_STANDSTILL] = "full service brake to standstill"
        return found

    def _enter(self, rule: TransitionRule, now_s: float, reason: str) -> None:
        target = rule.target
        self.transitions.append(
            AtoTransition(
                time_s=now_s, source=self.state, target=target, trigger=rule.trigger, reason=reason
            )
        )
        self.state = target
        self._entered_s = now_s
        if target is _S.ENGAGED:
            self._automatic_driving_seen = False
            self._moved_since_engaged = False
        if target not in (_S.ENGAGED, _S.DISENGAGING):
            self._fallback_stop = False
        if target is _S.CONFIGURATION:
            self._link_reference_s = now_s
        self._continue_after_dwell = rule.trigger is Trigger.STOPPED_AT_STOPPING_POINT or (
            self._continue_after_dwell and target in (_S.AVAILABLE, _S.READY)
        )

    # -- operator's requests --------------------------------------------------------------------

    def engage(self, now_s: float) -> None:
        """The remote driver's "ATO Engage": RE → EG; refused in any other state."""
        self._check_time(now_s)
        rule = select_rule(self.state, {Trigger.ENGAGE_REQUESTED})
        if rule is None:
            reasons = self.output.unavailable_reasons + self.output.not_ready_reasons
            detail = f" ({', '.join(reasons)})" if reasons else ""
            raise RequestRefusedError(f"engage refused: ATO-OB in {self.state}, not RE{detail}")
        self._enter(rule, now_s, "engage requested by the remote driver")
        self.output = self._output(now_s)

    def disengage(self, now_s: float) -> None:
        """The remote driver's "ATO Disengage": EG or DE → NA.

        In AV and RE it cancels the automatic continuation after a stop, so that the vehicle
        stays where it is. Refused in NP, CO, NA and FA, where there is nothing to disengage.
        """
        self._check_time(now_s)
        rule = select_rule(self.state, {Trigger.DISENGAGE_REQUESTED})
        if rule is not None:
            self._enter(rule, now_s, "disengage requested by the remote driver")
        elif self.state in (_S.AVAILABLE, _S.READY):
            self._continue_after_dwell = False
        else:
            raise RequestRefusedError(f"disengage refused: nothing engaged in {self.state}")
        self.output = self._output(now_s)

    def reset(self, now_s: float) -> None:
        """The operator's reset after a failure: FA → CO, once the cause has cleared."""
        self._check_time(now_s)
        if self.state is not _S.FAILURE:
            raise RequestRefusedError(f"reset refused: ATO-OB in {self.state}, not FA")
        causes = self._fault_causes(now_s)
        if causes:
            raise RequestRefusedError(
                "reset refused: the fault remains (" + ", ".join(causes) + ")"
            )
        rule = select_rule(self.state, {Trigger.RESET})
        if rule is None:  # pragma: no cover - row 4 of the table
            raise RequestRefusedError("reset refused: no transition")
        self._enter(rule, now_s, "reset by the operator, the fault cleared")
        self.output = self._output(now_s)

    # -- conditions -----------------------------------------------------------------------------

    def _check_time(self, now_s: float) -> None:
        if not math.isfinite(now_s) or now_s < self._time_s:
            raise AtoObInputError(f"time {now_s} s is not finite or before {self._time_s} s")
        self._time_s = now_s

    def _link_alive(self, now_s: float) -> bool:
        last_s = self._link_reference_s if self._etcs is None else self._etcs.received_s
        return now_s - last_s <= self.etcs_link_timeout_s

    def _fault_causes(self, now_s: float) -> tuple[Condition, ...]:
        causes: list[Condition] = []
        if not self._link_alive(now_s):
            causes.append(Condition.ETCS_LINK)
        if self._inputs is not None and self._inputs.internal_fault:
            causes.append(Condition.NO_INTERNAL_FAULT)
        return tuple(causes)

    def _configuration_failures(self, now_s: float, inputs: AtoObInputs) -> tuple[Condition, ...]:
        link_up = self._etcs is not None and self._link_alive(now_s)
        return failed_configuration_conditions(inputs, etcs_link_alive=link_up)

    def _operational_failures(self, now_s: float, inputs: AtoObInputs) -> tuple[Condition, ...]:
        engaged = self.state is _S.ENGAGED
        # Once engaged, FS no longer does: ETCS must have entered AD, or be given time to.
        automatic_driving_required = engaged and (
            self._automatic_driving_seen or now_s - self._entered_s > self.automatic_driving_entry_s
        )
        return failed_operational_conditions(
            inputs,
            self._etcs,
            automatic_driving_required=automatic_driving_required,
            end_of_journey_pending=engaged and not inputs.standstill,
        )

    def _disengaging_expired(self, now_s: float) -> bool:
        return self.state is _S.DISENGAGING and now_s - self._entered_s >= self.disengaging_s

    # -- outputs --------------------------------------------------------------------------------

    def _reasons(self, now_s: float) -> tuple[tuple[Condition, ...], tuple[Condition, ...]]:
        inputs = self._inputs
        if inputs is None or self.state is _S.NP:
            return (), ()
        if self.state is _S.CONFIGURATION:
            unavailable = self._configuration_failures(now_s, inputs)
        elif self.state is _S.FAILURE:
            unavailable = self._fault_causes(now_s)
        else:
            unavailable = self._operational_failures(now_s, inputs)
        return unavailable, failed_engagement_conditions(inputs)

    def _mode_request(self, now_s: float) -> ModeRequest:
        if self.state is _S.ENGAGED:
            return ModeRequest.AUTONOMOUS
        if self.state is _S.DISENGAGING:
            # The profile is followed without traction until the full service brake.
            expired = self._disengaging_expired(now_s)
            return ModeRequest.OFF if expired else ModeRequest.AUTONOMOUS
        remote = self._inputs is not None and self._inputs.remote_driving_selected
        if self.state in _DRIVER_STATES and remote:
            return ModeRequest.REMOTE
        return ModeRequest.OFF

    def _output(self, now_s: float) -> AtoObOutput:
        state, etcs = self.state, self._etcs
        mode_request = self._mode_request(now_s)
        traction_cut = etcs is not None and etcs.traction_cut
        traction_allowed = not traction_cut and (
            state is _S.ENGAGED or (state in _DRIVER_STATES and mode_request is ModeRequest.REMOTE)
        )
        full_service_brake = state is _S.FAILURE or self._disengaging_expired(now_s)
        remaining_s = None
        if state is _S.DISENGAGING:
            remaining_s = max(0.0, self.disengaging_s - (now_s - self._entered_s))
        unavailable, not_ready = self._reasons(now_s)
        return AtoObOutput(
            time_s=now_s,
            state=state,
            mode_request=mode_request,
            automatic_driving_requested=state is _S.ENGAGED,
            traction_allowed=traction_allowed,
            full_service_brake=full_service_brake,
            stop_at_next_stopping_point=self._fallback_stop and state is _S.ENGAGED,
            continue_after_dwell=self._continue_after_dwell,
            failure_warning=(
                state is _S.FAILURE and now_s - self._entered_s < self.failure_warning_s
            ),
            disengaging_remaining_s=remaining_s,
            unavailable_reasons=unavailable,
            not_ready_reasons=not_ready,
            permitted_speed_mps=0.0 if etcs is None else etcs.permitted_speed_mps,
            end_of_authority_distance_m=None if etcs is None else etcs.end_of_authority_distance_m,
            supervised_location_distance_m=(
                None if etcs is None else etcs.supervised_location_distance_m
            ),
        )
