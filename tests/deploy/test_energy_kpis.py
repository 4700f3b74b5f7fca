"""Seed 003 §7 KPIs of a run: the SOC's minimum, timed from the start and from the cruise."""

from __future__ import annotations

import numpy as np
from numpy.testing import assert_allclose

from deploy.scenario.kpis import _energy_kpis


def _columns(
    soc: np.ndarray, speed_mps: np.ndarray, reference_mps: np.ndarray
) -> dict[str, np.ndarray]:
    times = np.arange(soc.size, dtype=float)
    extender = np.where(times >= np.argmin(soc), 100.0, 80.0)
    return {
        "time_s": times,
        "soc": soc,
        "speed_mps": speed_mps,
        "reference_speed_mps": reference_mps,
        "range_extender_kw": extender,
    }


def test_the_soc_minimum_is_timed_from_the_start_and_from_the_cruise() -> None:
    times = np.arange(2000, dtype=float)
    speed = np.minimum(times * 0.5, 200 / 3.6)  # 200 km/h reached after 111.1 s
    reference = np.minimum(times * 0.5 + 1.0, 200 / 3.6)
    soc = 0.55 - 0.0001 * np.minimum(times, 1500.0) + 0.00001 * np.maximum(times - 1500.0, 0.0)
    kpis = _energy_kpis(_columns(soc, speed, reference))
    assert kpis["soc_min_time_s"] == 1500.0
    # 199 km/h, the cruise's threshold, is reached at 110.6 s: sample 111.
    from_cruise_s = kpis["soc_min_time_from_cruise_s"]
    extender_kw = kpis["range_extender_kw_after_soc_min"]
    assert from_cruise_s is not None
    assert extender_kw is not None
    assert_allclose(from_cruise_s, 1500.0 - 111.0, atol=1e-9)
    assert_allclose(extender_kw, 100.0, atol=1e-9)


def test_without_a_reference_speed_there_is_no_cruise() -> None:
    soc = np.linspace(0.9, 0.8, 50)
    nan = np.full(50, np.nan)
    kpis = _energy_kpis(_columns(soc, np.zeros(50), nan))
    assert kpis["soc_min_time_s"] == 49.0
    assert kpis["soc_min_time_from_cruise_s"] is None


def test_plants_without_a_powertrain_have_no_energy_kpis() -> None:
    nan = np.full(10, np.nan)
    kpis = _energy_kpis(_columns(nan, np.zeros(10), nan))
    assert all(value is None for value in kpis.values())
