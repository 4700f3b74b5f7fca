"""Fixed values, national values and train data: the numbers behind the curves and supervision.

- :class:`FixedValues`: SUBSET-026 Appendix A.3.1, the same for every line (DOMAIN.md §1.1):
  the ceiling-speed margin laws, T_warning, T_driver, the M_rotating range, A_est2's bound.
- :class:`NationalValues`: the A.3.2 defaults (DOMAIN.md §1.5). A line may send others
  (packet 3), so they are configuration, not constants.
- :class:`TrainData`: the vehicle's braking capability and timing (SUBSET-026 §3.13.2–3.13.3).
  :data:`URV_TRAIN_DATA` describes the 15 t inspection vehicle; every number in it is an
  assumption (⚠) because the seeds give none, kept consistent with the plant's URV parameters
  (``onboard/plant/point_mass.py``: 15 t, 15 kN full brake, 8 % rotating mass).

Speeds are in m/s, built from the km/h of the specification with
:data:`protocol.units.MPS_PER_KMH`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields
from enum import StrEnum

from onboard.etcs._exceptions import TrainDataError
from protocol.units import MPS_PER_KMH

__all__ = [
    "FIXED_VALUES",
    "NATIONAL_DEFAULTS",
    "URV_TRAIN_DATA",
    "BrakeModelType",
    "FixedValues",
    "NationalValues",
    "TrainData",
    "conversion_model_build_up_times_s",
]


def _check_finite(instance: object) -> None:
    for field in fields(instance):  # type: ignore[arg-type]
        value = getattr(instance, field.name)
        if isinstance(value, float) and math.isnan(value):
            raise TrainDataError(f"{type(instance).__name__}.{field.name} is NaN")


@dataclass(frozen=True, kw_only=True)
class FixedValues:
    """SUBSET-026 A.3.1 fixed values (DOMAIN.md §1.1), in SI units.

    Each ceiling-speed margin dV grows linearly from ``dv_*_min`` at ``v_*_min`` to ``dv_*_max``
    at ``v_*_max`` (speeds of the MRSP, or of the LOA).
    """

    dv_ebi_min_mps: float = 7.5 * MPS_PER_KMH
    dv_ebi_max_mps: float = 15.0 * MPS_PER_KMH
    v_ebi_min_mps: float = 110.0 * MPS_PER_KMH
    v_ebi_max_mps: float = 210.0 * MPS_PER_KMH
    dv_sbi_min_mps: float = 5.5 * MPS_PER_KMH
    dv_sbi_max_mps: float = 10.0 * MPS_PER_KMH
    v_sbi_min_mps: float = 110.0 * MPS_PER_KMH
    v_sbi_max_mps: float = 210.0 * MPS_PER_KMH
    dv_warning_min_mps: float = 4.0 * MPS_PER_KMH
    dv_warning_max_mps: float = 5.0 * MPS_PER_KMH
    v_warning_min_mps: float = 110.0 * MPS_PER_KMH
    v_warning_max_mps: float = 140.0 * MPS_PER_KMH
    t_warning_s: float = 2.0
    t_driver_s: float = 4.0
    m_rotating_min_percent: float = 2.0
    m_rotating_max_percent: float = 15.0
    a_est2_max_mps2: float = 0.4
    """Upper bound of A_est2, the acceleration assumed during T_berem (§3.13.9.3.2.9)."""

    def __post_init__(self) -> None:
        _check_finite(self)
        for name in ("ebi", "sbi", "warning"):
            dv_min = getattr(self, f"dv_{name}_min_mps")
            dv_max = getattr(self, f"dv_{name}_max_mps")
            v_min = getattr(self, f"v_{name}_min_mps")
            v_max = getattr(self, f"v_{name}_max_mps")
            if not (0.0 <= dv_min <= dv_max and 0.0 <= v_min < v_max):
                raise TrainDataError(f"dV_{name}: needs 0 ≤ min ≤ max and 0 ≤ V_min < V_max")
        if self.t_warning_s < 0 or self.t_driver_s < 0 or self.a_est2_max_mps2 < 0:
            raise TrainDataError("T_warning, T_driver and A_est2's bound must not be negative")
        if not 0.0 <= self.m_rotating_min_percent <= self.m_rotating_max_percent:
            raise TrainDataError("M_rotating: needs 0 ≤ min ≤ max [%]")


@dataclass(frozen=True, kw_only=True)
class NationalValues:
    """SUBSET-026 A.3.2 national values at their defaults (DOMAIN.md §1.5), in SI units.

    Used here: the mode speeds V_NVSTFF (SR) and V_NVONSIGHT (OS), D_NVROLL (roll-away),
    D_NVSTFF (SR distance), Q_NVLOCACC, Q_NVEMRRLS, Q_NVSBTSMPERM, Q_NVSBFBPERM,
    Q_NVINHSMICPERM, M_NVAVADH and the integrated correction factors of lambda trains. The
    others are kept so that the set is complete and a line can carry its own.
    """

    v_nvshunt_mps: float = 30.0 * MPS_PER_KMH
    v_nvstff_mps: float = 40.0 * MPS_PER_KMH
    v_nvonsight_mps: float = 30.0 * MPS_PER_KMH
    v_nvlimsuperv_mps: float = 100.0 * MPS_PER_KMH
    v_nvunfit_mps: float = 100.0 * MPS_PER_KMH
    v_nvrel_mps: float = 40.0 * MPS_PER_KMH
    d_nvroll_m: float = 2.0
    d_nvpotrp_m: float = 200.0
    d_nvstff_m: float = math.inf
    """Maximum distance in SR; ⚠ not in DOMAIN.md, A.3.2 gives "infinite" as the default."""
    q_nvlocacc_m: float = 12.0
    emergency_brake_release_at_standstill: bool = True
    """Q_NVEMRRLS: EB revoked only at standstill (True) or once its cause has gone (False)."""
    service_brake_in_target_speed_monitoring: bool = True
    """Q_NVSBTSMPERM: the service brake may be used in TSM; otherwise the EB is commanded."""
    service_brake_feedback: bool = False
    """Q_NVSBFBPERM: brake-pressure feedback; changes T_indication to 5 s + T_driver."""
    inhibit_speed_accuracy_compensation: bool = False
    """Q_NVINHSMICPERM: V_δ0 = 0 instead of V_ura."""
    m_nvebcl: float = 0.999999999
    """Emergency-brake confidence level the train's Kdry_rst is given for."""
    m_nvavadh: float = 0.0
    kr_int: float = 0.9
    kv_int: float = 0.7
    kt_int: float = 1.1
    a_nvmaxredadh1_mps2: float = 1.0
    a_nvmaxredadh2_mps2: float = 0.7
    a_nvmaxredadh3_mps2: float = 0.7

    def __post_init__(self) -> None:
        _check_finite(self)
        speeds = [f.name for f in fields(self) if f.name.endswith("_mps")]
        if any(getattr(self, name) < 0 for name in speeds):
            raise TrainDataError("national speeds must not be negative")
        if self.d_nvroll_m < 0 or self.d_nvstff_m <= 0 or self.q_nvlocacc_m < 0:
            raise TrainDataError("D_NVROLL, Q_NVLOCACC ≥ 0 and D_NVSTFF > 0 are required")
        if not 0.0 <= self.m_nvavadh <= 1.0:
            raise TrainDataError("M_NVAVADH must lie in [0, 1]")
        if not (0.0 < self.kr_int <= 1.5 and 0.0 < self.kv_int <= 1.5 and self.kt_int > 0.0):
            raise TrainDataError("the integrated correction factors must be positive")


class BrakeModelType(StrEnum):
    """How A_brake_safe and T_be come from the train's brake data (DOMAIN.md §1.4)."""

    GAMMA = "gamma"
    """Decelerations given directly: A_brake_safe uses Kdry_rst and Kwet_rst; T_be = T_eb."""
    LAMBDA = "lambda"
    """Conversion-model train: A_brake_safe = Kv_int·Kr_int·A_eb; T_be = Kt_int·T_eb."""


@dataclass(frozen=True, kw_only=True)
class TrainData:
    """The train data the braking curves use (SUBSET-026 §3.13.2.2, §3.13.3).

    Decelerations are on level track, rotating masses included (positive values). For a
    lambda train, ``t_brake_*_s`` are the conversion model's times for V_target = 0; they are
    multiplied by 1.2 for a target speed above 0 (DOMAIN.md §1.4).
    """

    length_m: float
    max_speed_mps: float
    brake_model: BrakeModelType
    a_brake_emergency_mps2: float
    a_brake_service_mps2: float
    t_brake_emergency_s: float
    t_brake_service_s: float
    t_traction_cut_off_s: float
    traction_cut_off_implemented: bool = True
    service_brake_available: bool = True
    kdry_rst: float = 1.0
    """Gamma trains: dry-rail correction at the confidence level M_NVEBCL."""
    kwet_rst: float = 1.0
    """Gamma trains: wet-rail correction."""
    rotating_mass_percent: float | None = None
    """Nominal M_rotating [%]; None uses M_rotating_max uphill and M_rotating_min downhill."""

    def __post_init__(self) -> None:
        _check_finite(self)
        if not (0.0 < self.length_m <= 2000.0 and 0.0 < self.max_speed_mps <= 600.0 * MPS_PER_KMH):
            raise TrainDataError("train length must be in (0, 2000] m, max speed in (0, 600] km/h")
        if self.a_brake_emergency_mps2 <= 0 or self.a_brake_service_mps2 <= 0:
            raise TrainDataError("brake decelerations must be positive [m/s²]")
        if min(self.t_brake_emergency_s, self.t_brake_service_s, self.t_traction_cut_off_s) < 0:
            raise TrainDataError("brake build-up and traction cut-off times must not be negative")
        if not (0.0 < self.kdry_rst <= 1.0 and 0.0 < self.kwet_rst <= 1.0):
            raise TrainDataError("Kdry_rst and Kwet_rst must lie in (0, 1]")
        if self.rotating_mass_percent is not None and not 0 <= self.rotating_mass_percent <= 100:
            raise TrainDataError("M_rotating_nom must lie in [0, 100] %")


def conversion_model_build_up_times_s(length_m: float) -> tuple[float, float]:
    """(T_brake_emergency, T_brake_service) [s] of the conversion model, passenger train in P.

    DOMAIN.md §1.4, for V_target = 0 (multiply by 1.2 for V_target > 0)::

        T_brake_basic_eb = 2.30 + 0.17·(L/100)²,  L taken at least 400 m
        T_brake_basic_sb = 3.00 + 1.5·(L/100) + 0.1·(L/100)²

    Valid for L ≤ 900 m.
    """
    if not 0.0 < length_m <= 900.0:
        raise TrainDataError(f"the conversion model holds for 0 < L ≤ 900 m, not {length_m} m")
    hectometres_eb = max(length_m, 400.0) / 100.0
    hectometres = length_m / 100.0
    return 2.30 + 0.17 * hectometres_eb**2, 3.00 + 1.5 * hectometres + 0.1 * hectometres**2


FIXED_VALUES = FixedValues()
NATIONAL_DEFAULTS = NationalValues()

_URV_MASS_KG = 15_000.0
_URV_MAX_BRAKE_FORCE_N = 15_000.0
_URV_ROTATING_MASS_FACTOR = 0.08

URV_TRAIN_DATA = TrainData(
    # ⚠ Assumed: a single-bogie vehicle under a small carbody ("closer to an SUV than a train").
    length_m=10.0,
    # Seed 003: the mission runs at up to 200 km/h.
    max_speed_mps=200.0 * MPS_PER_KMH,
    # It brakes to a given deceleration; no brake percentage, so no conversion model.
    brake_model=BrakeModelType.GAMMA,
    # The plant's full brake, 15 kN on 15 t with 8 % rotating mass, on level track: 0.926 m/s²
    # ("about 1 m/s²"); the Davis resistance, which only helps, is left out.
    a_brake_emergency_mps2=_URV_MAX_BRAKE_FORCE_N
    / (_URV_MASS_KG * (1 + _URV_ROTATING_MASS_FACTOR)),
    # ⚠ Full service brake of about 0.7 m/s² (the ADF plans at 0.6 m/s², inside it).
    a_brake_service_mps2=0.7,
    # ⚠ One vehicle, no brake pipe to propagate along: seed 004 allows 450 ms to depressurise
    # and the plant's brake lags 0.3 s; 1.0 s keeps a margin. Service (blended) 1.5 s.
    t_brake_emergency_s=1.0,
    t_brake_service_s=1.5,
    # ⚠ Electric drives drop their torque within half a second.
    t_traction_cut_off_s=0.5,
    # ⚠ Adhesion corrections for the gamma train: 0.9 × 0.9 leaves A_brake_safe ≈ 0.75 m/s².
    kdry_rst=0.9,
    kwet_rst=0.9,
)
"""Train data of the URV inspection vehicle (assumed values, see the comments)."""
