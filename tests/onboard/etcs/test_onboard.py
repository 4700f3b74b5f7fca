"""EtcsOnboard as a whole: a lap of the seed ring, determinism, typed errors, the public API."""

from __future__ import annotations

import importlib
import math
import pkgutil
from collections.abc import Callable
from dataclasses import replace

import pytest

import onboard.etcs
from onboard.etcs import (
    URV_TRAIN_DATA,
    EtcsError,
    EtcsInputError,
    EtcsOnboard,
    EtcsOutput,
    FixedValues,
    NationalValues,
    TrainData,
    TrainDataError,
)
from protocol.messages import EtcsMode
from protocol.units import MPS_PER_KMH
from tests.onboard.etcs.layouts import in_full_supervision, level_line
from trackdb import TrackMap, load_seed_line

DT_S = 0.2


def _lap(track_map: TrackMap, *, steps: int = 2_000) -> list[EtcsOutput]:
    """A driver that keeps 1.5 m/s under the permitted speed, from SR at the origin."""
    etcs = EtcsOnboard(track_map, position_m=0.0)
    etcs.start_of_mission(0.0)
    position_m = speed_mps = 0.0
    outputs = []
    for k in range(1, steps):
        out = etcs.step(k * DT_S, position_m % track_map.length_m, speed_mps)
        outputs.append(out)
        aim_mps = out.permitted_speed_mps - 1.5
        acceleration = 0.5 if speed_mps < aim_mps else -0.6 if speed_mps > aim_mps + 0.5 else 0
        speed_mps = max(0.0, speed_mps + acceleration * DT_S)
        position_m += speed_mps * DT_S
        if position_m > track_map.length_m + 200.0:
            break
    return outputs


def test_a_lap_of_the_seed_ring_runs_in_full_supervision_without_intervention() -> None:
    outputs = _lap(TrackMap(load_seed_line("bologna-ring")))
    modes = [o.mode for o in outputs]
    assert modes[0] is EtcsMode.SR
    assert modes[-1] is EtcsMode.FS
    assert set(modes) == {EtcsMode.SR, EtcsMode.FS}
    assert not any(o.service_brake or o.emergency_brake for o in outputs)
    assert {o.lrbg_id for o in outputs} == {None, 101, 102, 103, 104}
    # The permitted speed reached the 80 km/h line speed and the 60 km/h curves.
    permitted_kmh = {round(o.permitted_speed_mps / MPS_PER_KMH) for o in outputs}
    assert {40, 60, 80} <= permitted_kmh
    assert all(
        o.end_of_authority_distance_m is None or o.end_of_authority_distance_m > 500
        for o in outputs
    )


def test_the_same_inputs_give_the_same_outputs() -> None:
    track_map = TrackMap(load_seed_line("bologna-ring"))
    first, second = _lap(track_map, steps=700), _lap(track_map, steps=700)
    assert first[-1].mode is EtcsMode.FS
    assert first == second


@pytest.mark.parametrize(
    ("now_s", "position_m", "speed_mps", "acceleration_mps2"),
    [
        (1.0, 0.0, -1.0, 0.0),
        (1.0, 0.0, math.nan, 0.0),
        (1.0, math.inf, 1.0, 0.0),
        (1.0, 0.0, 1.0, math.nan),
        (math.nan, 0.0, 1.0, 0.0),
        (-1.0, 0.0, 1.0, 0.0),
    ],
)
def test_bad_step_inputs_raise_typed_errors(
    now_s: float, position_m: float, speed_mps: float, acceleration_mps2: float
) -> None:
    etcs = EtcsOnboard(level_line(), position_m=0.0)
    with pytest.raises(EtcsInputError) as caught:
        etcs.step(now_s, position_m, speed_mps, acceleration_mps2=acceleration_mps2)
    assert isinstance(caught.value, EtcsError)
    assert isinstance(caught.value, ValueError)


def test_time_must_not_go_back_across_calls() -> None:
    etcs = in_full_supervision(level_line(), position_m=0.0, end_of_authority_m=9e3)
    etcs.step(5.0, 0.0, 0.0)
    with pytest.raises(EtcsInputError):
        etcs.isolate(4.9)
    with pytest.raises(EtcsInputError):
        etcs.step(4.0, 0.0, 0.0)


@pytest.mark.parametrize(
    "build",
    [
        lambda: replace(URV_TRAIN_DATA, a_brake_emergency_mps2=0.0),
        lambda: replace(URV_TRAIN_DATA, kdry_rst=1.2),
        lambda: replace(URV_TRAIN_DATA, length_m=math.nan),
        lambda: replace(URV_TRAIN_DATA, t_brake_service_s=-1.0),
        lambda: NationalValues(m_nvavadh=2.0),
        lambda: NationalValues(v_nvstff_mps=-1.0),
        lambda: FixedValues(dv_ebi_min_mps=5.0, dv_ebi_max_mps=1.0),
        lambda: FixedValues(m_rotating_min_percent=20.0),
    ],
)
def test_bad_values_raise_train_data_errors(build: Callable[[], object]) -> None:
    with pytest.raises(TrainDataError):
        build()


def test_train_data_is_frozen() -> None:
    with pytest.raises(AttributeError):
        URV_TRAIN_DATA.length_m = 1.0  # type: ignore[misc]
    assert isinstance(URV_TRAIN_DATA, TrainData)


def _modules() -> list[str]:
    names = ["onboard.etcs"]
    for info in pkgutil.walk_packages(onboard.etcs.__path__, prefix="onboard.etcs."):
        names.append(info.name)
    return names


@pytest.mark.parametrize("name", _modules())
def test_every_module_has_a_complete_all(name: str) -> None:
    module = importlib.import_module(name)
    exported = getattr(module, "__all__", None)
    assert exported is not None, name
    assert [item for item in exported if not hasattr(module, item)] == []


def test_the_errors_are_re_exported() -> None:
    errors = importlib.import_module("onboard.etcs._exceptions")
    assert set(errors.__all__) <= set(onboard.etcs.__all__)
    for name in errors.__all__:
        assert issubclass(getattr(errors, name), EtcsError)
