"""The Autonomous Driving Function (seed 000 §5): supervisory controller and its controllers.

Abbreviations: RD / AD (remote / autonomous driving), NMPC (nonlinear model predictive control),
ODP (optimal driving profile).
"""

from onboard.adf.nmpc import NmpcConfig, NmpcController, NmpcReference, NmpcResult, NmpcStats
from onboard.adf.rd_controller import RemoteDrivingController, RemoteDrivingGains

__all__ = [
    "NmpcConfig",
    "NmpcController",
    "NmpcReference",
    "NmpcResult",
    "NmpcStats",
    "RemoteDrivingController",
    "RemoteDrivingGains",
]
