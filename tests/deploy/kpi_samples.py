"""Small, valid KPIs of a whole-stack run for tests that judge or summarise them."""

from __future__ import annotations

from typing import Any

from deploy.scenario.kpi_model import Kpis

__all__ = ["sample_kpis"]


def sample_kpis(**changes: Any) -> Kpis:
    """A whole-stack run of one stop that kept every invariant, with ``changes`` (validated:
    nested values may be given as dicts)."""
    fields: dict[str, Any] = {
        "scenario": "sample",
        "passed": True,
        "seed": 0,
        "sim_time_s": 120.0,
        "wall_time_s": 10.0,
        "real_time_factor": 12.0,
        "stops": [
            {
                "name": "tp1-north",
                "planned_arrival_s": 100.0,
                "arrival_error_s": 1.0,
                "stop_error_m": 0.1,
                "odometry_interval_m": 5.0,
            }
        ],
        "max_overspeed_kmh": 0.0,
        "etcs_sb_count": 0,
        "etcs_eb_count": 0,
        "vc_eb_count": 0,
        "system_decay": False,
        "traction_energy_kwh": 0.5,
        "regen_energy_kwh": 0.0,
        "max_jerk_mps3": 0.8,
        "ad_speed_rms_kmh": 0.4,
        "rd_speed_rms_kmh": None,
        "max_switch_du_frac": None,
        "position_error_m": {"rms": 0.2, "max": 0.4},
        "nmpc_ms": {"p50": 1.0, "p99": 4.0, "max": 9.0},
        "nmpc_failures": 0,
        "nmpc_fallback_s": 0.0,
        "vc_interventions": [],
        "max_speed_over_cap_kmh": 0.0,
        "min_eoa_margin_m": 50.0,
        "eoa_stops": [{"time_s": 90.0, "distance_to_eoa_m": 6.4, "odometry_interval_m": 4.0}],
        "actions": [],
        "expectations": [],
    }
    return Kpis.model_validate(fields | changes)
