"""Status reports for the trackside's tests: a train in AD at a place on a line."""

from __future__ import annotations

from protocol import messages as m


def status_report(
    vehicle_id: str,
    position_m: float,
    *,
    line_id: str,
    confidence_m: float | None = 2.0,
) -> m.StatusReport:
    """A report of ``vehicle_id`` engaged in AD at 5 m/s, its front end at ``position_m`` on
    ``line_id`` with a confidence interval of ``confidence_m`` (None: no ETCS position)."""
    return m.StatusReport(
        vehicle_id=vehicle_id,
        seq=0,
        sim_time_s=0.0,
        line_id=line_id,
        position_m=position_m,
        speed_mps=5.0,
        acceleration_mps2=0.0,
        traction_force_n=0.0,
        ato_state=m.AtoState.ENGAGED,
        etcs_mode=m.EtcsMode.FS,
        sc_state=m.ScState.AD,
        position_confidence_m=confidence_m,
    )
