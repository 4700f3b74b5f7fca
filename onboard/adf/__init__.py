"""The Autonomous Driving Function (seed 000 §5): supervisory controller and its controllers."""

from onboard.adf.rd_controller import RemoteDrivingController, RemoteDrivingGains

__all__ = ["RemoteDrivingController", "RemoteDrivingGains"]
