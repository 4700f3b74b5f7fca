"""Inputs and a small driver for the ATO-OB controller's tests.

- ``inputs``: the nominal inputs at a time (ETCS in FS with an MA, everything valid, at a
  stopping point at standstill with the dwell elapsed), with any field changed.
- ``Drive``: a controller with its clock; ``Drive.at`` / ``Drive.next`` run a cycle.
- ``in_state``: a drive brought to a given state by the nominal path.
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any

from onboard.ato_ob import AtoObController, AtoObInputs, AtoObOutput, EtcsStatus
from protocol.messages import AtoState, EtcsMode

__all__ = ["DT_S", "Drive", "etcs_status", "in_state", "inputs"]

DT_S = 0.1
PERMITTED_MPS = 22.0
EOA_M = 1_500.0
SVL_M = 1_550.0


def etcs_status(now_s: float, *, mode: EtcsMode = EtcsMode.FS, **changes: Any) -> EtcsStatus:
    """An ETCS-OB output received at ``now_s``: no brake, permitted 22 m/s, EoA 1500 m."""
    status = EtcsStatus(
        mode=mode,
        service_brake=False,
        emergency_brake=False,
        permitted_speed_mps=PERMITTED_MPS,
        end_of_authority_distance_m=EOA_M,
        supervised_location_distance_m=SVL_M,
        received_s=now_s,
    )
    return replace(status, **changes)


def inputs(
    now_s: float,
    *,
    mode: EtcsMode = EtcsMode.FS,
    etcs: dict[str, Any] | None = None,
    link: bool = True,
    **changes: Any,
) -> AtoObInputs:
    """The nominal inputs at ``now_s``; ``link=False`` passes no new ETCS-OB output."""
    nominal = AtoObInputs(
        etcs=etcs_status(now_s, mode=mode, **(etcs or {})) if link else None,
        journey_profile_valid=True,
        journey_profile_accepted=True,
        track_data_version_matches=True,
        localisation_valid=True,
        end_of_journey_reached=False,
        standstill=True,
        at_stopping_point=True,
        dwell_elapsed=True,
        movement_authority_allows_departure=True,
        distance_to_next_stop_sufficient=True,
        trackside_session_alive=True,
    )
    return replace(nominal, **changes)


class Drive:
    """A controller and its clock, stepped with :func:`inputs`."""

    def __init__(self, controller: AtoObController | None = None) -> None:
        self.controller = controller or AtoObController()
        self.now_s = 0.0

    @property
    def state(self) -> AtoState:
        return self.controller.state

    def at(self, now_s: float, **changes: Any) -> AtoObOutput:
        """A cycle at ``now_s`` with the nominal inputs changed by ``changes``."""
        self.now_s = now_s
        return self.controller.step(now_s, inputs(now_s, **changes))

    def next(self, **changes: Any) -> AtoObOutput:
        """A cycle one period later."""
        return self.at(round(self.now_s + DT_S, 9), **changes)

    def engaged_and_running(self) -> AtoObOutput:
        """From RE: engage, then a cycle running in AD."""
        self.controller.engage(self.now_s)
        return self.next(mode=EtcsMode.AD, standstill=False, at_stopping_point=False)


def in_state(state: AtoState) -> Drive:
    """A drive brought to ``state`` by the nominal path (FA by an internal fault from NA)."""
    drive = Drive()
    if state is AtoState.NP:
        return drive
    drive.at(0.0)  # NP → CO
    if state is not AtoState.CONFIGURATION:
        drive.next(dwell_elapsed=False)  # CO → NA
    if state in (AtoState.AVAILABLE, AtoState.READY, AtoState.ENGAGED, AtoState.DISENGAGING):
        drive.next(dwell_elapsed=False)  # NA → AV
    if state in (AtoState.READY, AtoState.ENGAGED, AtoState.DISENGAGING):
        drive.next()  # AV → RE
    if state in (AtoState.ENGAGED, AtoState.DISENGAGING):
        drive.engaged_and_running()
    if state is AtoState.DISENGAGING:
        drive.next(etcs={"service_brake": True}, standstill=False, at_stopping_point=False)
    if state is AtoState.FAILURE:
        drive.next(internal_fault=True)
    assert drive.state is state
    return drive
