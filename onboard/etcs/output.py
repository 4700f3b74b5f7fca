"""What one ETCS cycle gives the rest of the onboard: :class:`EtcsOutput`.

The ADF, the ATO-OB controller and the VC take their constraints and commands from it; the
scenario's KPIs take the odometry from it (the estimated front end and its confidence
interval), to compare with the truth outside the onboard.
"""

from __future__ import annotations

from dataclasses import dataclass

from onboard.etcs.linking import LinkingEvent
from onboard.etcs.movement_authority import EtcsLevel
from onboard.etcs.odometer import WheelAdhesion
from onboard.etcs.odometry import ConfidenceInterval
from onboard.etcs.supervision import Monitoring
from protocol.messages import EtcsMode, SupervisionStatus

__all__ = ["EtcsOutput"]


@dataclass(frozen=True, kw_only=True)
class EtcsOutput:
    """One cycle's outcome: mode, supervision, the ADF's constraints and the commands."""

    time_s: float
    mode: EtcsMode
    level: EtcsLevel
    supervision_status: SupervisionStatus
    monitoring: Monitoring
    permitted_speed_mps: float
    """The speed not to exceed now [m/s]: 0 in SB, PT and TR; unsupervised MRSP in IS."""
    ceiling_speed_mps: float
    """The MRSP under the train [m/s], with the mode's limit."""
    target_speed_mps: float | None
    target_distance_m: float | None
    """From the relevant front end to the most restrictive target [m]."""
    release_speed_mps: float | None
    end_of_authority_m: float | None
    """The EoA's chainage [m]."""
    end_of_authority_distance_m: float | None
    """From the estimated front end to the EoA [m]."""
    supervised_location_distance_m: float | None
    """From the max-safe front end to the SvL [m]."""
    traction_cut: bool
    service_brake: bool
    emergency_brake: bool
    estimated_front_m: float
    """The estimated front end's chainage [m]."""
    odometry: ConfidenceInterval
    """The confidence interval, in the onboard's track coordinate (unwrapped on a ring): the
    estimated front end, the over-reading (ahead) and under-reading (behind) amounts, the
    distance travelled since the LRBG and the slip/slide share of the interval."""
    lrbg_id: int | None
    estimated_speed_mps: float = 0.0
    """V_est [m/s], the speed supervised: the odometer's on the sensor path."""
    estimated_acceleration_mps2: float = 0.0
    """A_est [m/s²]: the odometer's on the sensor path."""
    wheel_adhesion: WheelAdhesion = WheelAdhesion.ROLLING
    """Slip or slide while the odometer sees it; always rolling on the given-motion path."""
    linking_events: tuple[LinkingEvent, ...] = ()
    """Linked groups not read where expected since the last output, and the reaction taken."""

    @property
    def travelled_since_lrbg_m(self) -> float:
        """The distance [m] counted since the LRBG (since the start before the first)."""
        return self.odometry.travelled_since_reference_m
