"""The plant: the vehicle's truth (dynamics, actuators). Used for KPIs, never by the controllers."""

from onboard.plant.point_mass import URV_PARAMETERS, PointMassModel, PointMassParameters

__all__ = ["URV_PARAMETERS", "PointMassModel", "PointMassParameters"]
