"""The Autonomous Driving Function (seed 000 §5): supervisory controller and its controllers.

Abbreviations: RD / AD (remote / autonomous driving), NMPC (nonlinear model predictive control),
ODP (optimal driving profile).
"""

from onboard.adf.autonomous import AutonomousDriving
from onboard.adf.nmpc import NmpcConfig, NmpcController, NmpcReference, NmpcResult, NmpcStats
from onboard.adf.odp import InfeasibleLegError, LspbSegment, OdpPlan, lspb_segment, plan_legs
from onboard.adf.rd_controller import RemoteDrivingController, RemoteDrivingGains
from onboard.adf.supervisor import ModeRequest, SupervisoryController

__all__ = [
    "AutonomousDriving",
    "InfeasibleLegError",
    "LspbSegment",
    "ModeRequest",
    "NmpcConfig",
    "NmpcController",
    "NmpcReference",
    "NmpcResult",
    "NmpcStats",
    "RemoteDrivingController",
    "OdpPlan",
    "RemoteDrivingGains",
    "SupervisoryController",
    "lspb_segment",
    "plan_legs",
]
