"""The operator script's log of an issued MA: the same for the same run (``kpis.json``)."""

from __future__ import annotations

from typing import Any

from deploy.scenario.operator_script import ma_summary


def _answer(
    session_id: str, issued_at_s: float, authority: dict[str, Any] | None
) -> dict[str, Any]:
    return {
        "movement_authority": {
            "vehicle_id": "URV1",
            "ma_id": 3,
            "change": "issued" if authority else "revoked",
            "issued_at_s": issued_at_s,
            "authority": authority,
            "freshness": {"session_id": session_id, "number": 7},
        },
        "supervised_location_m": None,
        "acknowledgement": None,
    }


def test_an_issued_ma_is_logged_by_its_number_change_and_extent_not_its_session() -> None:
    authority = {"start_m": 500.0, "end_of_authority_m": 1999.94, "sections": []}
    first = ma_summary(_answer("Zq1", 1.8, authority))
    assert first == "MA 3 issued: 500.0 → 1999.9 m"
    assert ma_summary(_answer("other-session", 2.5, authority)) == first


def test_a_revoked_ma_is_logged_as_revoked() -> None:
    assert ma_summary(_answer("Zq1", 1.8, None)) == "MA 3 revoked: revoked"
