"""The simulated vehicle: the truth side of the onboard process.

:class:`SimulatedVehicle` is all of the onboard process that reads the vehicle's true state: the
dynamics (the point-mass model, or the 10-DOF bogie with its powertrain, :class:`BogiePlant`),
the line as the vehicle meets it (gradient, curvature, adhesion), and the sensor models. The node
steps it every plant tick with what the actuators are told (a force demand for the point mass,
the VCU's :class:`ActuatorCommands` for the bogie) and the emergency brake's share; everything
else in the process takes its outputs (:mod:`onboard.plant.readings` and the interface-modules'
UDP datagrams), never its state. Scenario runs, telemetry and KPIs read :attr:`truth`: that is
what a simulator is for.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Protocol

from onboard.plant.bogie import BogieModel
from onboard.plant.bogie_parameters import URV_BOGIE_PARAMETERS, BogieParameters
from onboard.plant.interfaces import ActuatorCommands, BogieTruth
from onboard.plant.point_mass import PointMassModel
from onboard.plant.powertrain import Powertrain, PowertrainParameters
from onboard.plant.readings import (
    BaliseDetection,
    DriveReading,
    MarkerDetection,
    PowertrainReading,
    WheelReading,
)
from onboard.plant.sensors import InterfaceModules, TruthSample, truth_from_bogie
from trackdb import TrackMap

__all__ = [
    "BaliseReaderModel",
    "BogiePlant",
    "Dynamics",
    "MarkerReaderModel",
    "SimulatedVehicle",
    "WheelSensorModel",
    "force_limits_n",
]


@dataclass(frozen=True, slots=True)
class _Step:
    dt_s: float
    gradient_permille: float
    curve_radius_m: float
    emergency_brake: float


class BogiePlant:
    """The 10-DOF bogie model and the series-hybrid powertrain, driven by actuator commands.

    The emergency brake acts below the VCU, as the brake pipe acts on the cylinders: motors
    off, each pneumatic brake at least the EB's share of its maximum pressure.
    """

    def __init__(
        self,
        parameters: BogieParameters = URV_BOGIE_PARAMETERS,
        *,
        position_m: float = 0.0,
        initial_soc: float = 0.9,
        powertrain: PowertrainParameters | None = None,
    ) -> None:
        self.parameters = parameters
        self.model = BogieModel(parameters, position_m=position_m)
        self.powertrain = Powertrain(powertrain or PowertrainParameters(), soc=initial_soc)
        self.adhesion_factor = 1.0
        """μ₀ of the wheel–rail contact is scaled by this: below 1 on a wet or leafy patch."""
        self.truth: BogieTruth = self.model.truth()

    def step(self, step: _Step, commands: ActuatorCommands) -> None:
        if step.emergency_brake > 0.0:
            pipe_pa = min(step.emergency_brake, 1.0) * self.parameters.brake_max_pressure_pa
            commands = dataclasses.replace(
                commands,
                motor_torque_front_nm=0.0,
                motor_torque_rear_nm=0.0,
                brake_pressure_front_pa=max(commands.brake_pressure_front_pa, pipe_pa),
                brake_pressure_rear_pa=max(commands.brake_pressure_rear_pa, pipe_pa),
            )
        self.model.step(
            step.dt_s,
            commands,
            gradient_permille=step.gradient_permille,
            adhesion_factor=self.adhesion_factor,
        )
        truth = self.truth = self.model.truth()
        self.powertrain.step(
            step.dt_s,
            mechanical_power_front_w=truth.motor_torque_front_nm * truth.wheel_speed_front_radps,
            mechanical_power_rear_w=truth.motor_torque_rear_nm * truth.wheel_speed_rear_radps,
            range_extender_reference_w=commands.range_extender_power_w,
            motor_torque_front_nm=truth.motor_torque_front_nm,
            motor_torque_rear_nm=truth.motor_torque_rear_nm,
        )

    @property
    def applied_force_n(self) -> float:
        """Motor minus brake torques over the wheel radius [N]: what the actuators apply."""
        t = self.truth
        motors = t.motor_torque_front_nm + t.motor_torque_rear_nm
        brakes = abs(t.brake_torque_front_nm) + abs(t.brake_torque_rear_nm)
        return (motors - brakes) / t.wheel_radius_m

    def powertrain_reading(self) -> PowertrainReading:
        """What the BMS, the range extender and the drives' sensors report."""
        powertrain = self.powertrain
        bms = powertrain.bms_status()
        return PowertrainReading(
            time_s=self.truth.time_s,
            soc=bms.soc,
            battery_voltage_v=bms.voltage_v,
            battery_current_a=bms.current_a,
            max_discharge_power_w=bms.max_discharge_power_w,
            max_charge_power_w=bms.max_charge_power_w,
            continuous_current_a=bms.continuous_current_a,
            range_extender_power_w=powertrain.range_extender.power_w,
            motor_temperature_front_c=powertrain.thermal_front.temperature_c,
            motor_temperature_rear_c=powertrain.thermal_rear.temperature_c,
        )


Dynamics = PointMassModel | BogiePlant
"""The vehicle's dynamics at either fidelity."""


def truth_sample(dynamics: Dynamics, time_s: float) -> TruthSample:
    """The truth the sensor models read, with the wheels' speeds on the bogie model."""
    if isinstance(dynamics, BogiePlant):
        return truth_from_bogie(dynamics.truth)
    return TruthSample(
        time_s=time_s,
        position_m=dynamics.position_m,
        speed_mps=dynamics.speed_mps,
        acceleration_mps2=dynamics.acceleration_mps2,
    )


def drive_reading(dynamics: Dynamics, time_s: float) -> DriveReading:
    """The drives' and brakes' feedback: the force they apply at the rail [N]."""
    return DriveReading(time_s=time_s, applied_force_n=dynamics.applied_force_n)


def force_limits_n(dynamics: Dynamics, speed_mps: float) -> tuple[float, float]:
    """(min, max) force [N] the vehicle's drives and brakes can deliver at ``speed_mps``: the
    vehicle data's traction and braking characteristics, not a reading of its state."""
    if isinstance(dynamics, PointMassModel):
        return dynamics.force_limits_n(speed_mps)
    p = dynamics.parameters
    radius = p.wheel_radius_m
    omega = max(speed_mps, 1.0) / radius
    torque = min(p.motor_max_torque_nm, p.motor_max_power_w / omega)
    brake = p.brake_gain_m3 * p.brake_max_pressure_pa
    return -2.0 * brake / radius, 2.0 * torque / radius


class WheelSensorModel(Protocol):
    """The axle-end sensors: the truth in, a :class:`WheelReading` out."""

    def step(self, truth: BogieTruth | TruthSample) -> WheelReading: ...


class BaliseReaderModel(Protocol):
    """The BTM and its antenna: the true front end in, the groups located under it out."""

    def step(self, time_s: float, front_position_m: float) -> Sequence[BaliseDetection]: ...


class MarkerReaderModel(Protocol):
    """The precision-stop marker reader: the true front end in, the markers found under it out."""

    def step(self, time_s: float, front_position_m: float) -> Sequence[MarkerDetection]: ...


class SimulatedVehicle:
    """The dynamics on the line, and the sensors that watch them.

    Parameters
    ----------
    track_map : TrackMap
        The line: gradient and curvature under the vehicle's true position.
    dynamics : PointMassModel or BogiePlant
        The vehicle's truth.
    interface_modules : InterfaceModules, optional
        The IMU, odometer and GPS emulator whose UDP datagrams feed the sensor-fusion listener.
    wheel_sensors, balise_reader, marker_reader : optional
        The axle-end sensors (ETCS's odometer, the VC's tachometer board, the VCU's slip
        protection), the BTM and the precision-stop marker reader.
    """

    def __init__(
        self,
        track_map: TrackMap,
        dynamics: Dynamics,
        *,
        interface_modules: InterfaceModules | None = None,
        wheel_sensors: WheelSensorModel | None = None,
        balise_reader: BaliseReaderModel | None = None,
        marker_reader: MarkerReaderModel | None = None,
        start_s: float = 0.0,
    ) -> None:
        self.track_map = track_map
        self.dynamics = dynamics
        self.interface_modules = interface_modules
        self.wheel_sensors = wheel_sensors
        self.balise_reader = balise_reader
        self.marker_reader = marker_reader
        self.time_s = start_s
        self._datagrams: list[bytes] = []
        self._wheel_readings: list[WheelReading] = []
        self._balises: list[BaliseDetection] = []
        self._markers: list[MarkerDetection] = []
        truth = self.truth
        if interface_modules is not None:
            self._datagrams.extend(interface_modules.start(truth))
        self.wheels: WheelReading | None = None
        if wheel_sensors is not None:
            self.wheels = wheel_sensors.step(self._wheel_truth(truth))

    # -- the truth: for scenario runs, telemetry, KPIs and tests only --------------------------

    @property
    def truth(self) -> TruthSample:
        """The vehicle's true state now."""
        return truth_sample(self.dynamics, self.time_s)

    @property
    def position_m(self) -> float:
        """True front end [m], unwrapped on a ring."""
        return (
            self.dynamics.truth.position_m
            if isinstance(self.dynamics, BogiePlant)
            else (self.dynamics.position_m)
        )

    @property
    def speed_mps(self) -> float:
        if isinstance(self.dynamics, BogiePlant):
            return max(self.dynamics.truth.speed_mps, 0.0)
        return self.dynamics.speed_mps

    @property
    def acceleration_mps2(self) -> float:
        if isinstance(self.dynamics, BogiePlant):
            return self.dynamics.truth.acceleration_mps2
        return self.dynamics.acceleration_mps2

    @property
    def applied_force_n(self) -> float:
        return self.dynamics.applied_force_n

    @property
    def traction_energy_j(self) -> float:
        if isinstance(self.dynamics, BogiePlant):
            return self.dynamics.truth.traction_energy_j
        return self.dynamics.traction_energy_j

    @property
    def regen_energy_j(self) -> float:
        if isinstance(self.dynamics, BogiePlant):
            return self.dynamics.truth.regen_energy_j
        return 0.0

    @property
    def powertrain(self) -> Powertrain | None:
        return self.dynamics.powertrain if isinstance(self.dynamics, BogiePlant) else None

    @property
    def adhesion_factor(self) -> float:
        """μ₀ of the wheel–rail contact is scaled by this (the bogie model; 1 otherwise)."""
        return self.dynamics.adhesion_factor if isinstance(self.dynamics, BogiePlant) else 1.0

    @adhesion_factor.setter
    def adhesion_factor(self, factor: float) -> None:
        if isinstance(self.dynamics, BogiePlant):
            self.dynamics.adhesion_factor = factor

    # -- stepping ------------------------------------------------------------------------------

    def step(
        self,
        now_s: float,
        dt_s: float,
        demand: float | ActuatorCommands,
        *,
        emergency_brake: float = 0.0,
    ) -> None:
        """Advance to ``now_s + dt_s`` [s] under ``demand`` (a force [N] for the point mass, the
        VCU's commands for the bogie) and the EB's share (0 to 1); then the sensors sample."""
        position = self.position_m
        track_map = self.track_map
        step = _Step(
            dt_s=dt_s,
            gradient_permille=track_map.gradient_permille(position),
            curve_radius_m=track_map.curve_radius_m(position),
            emergency_brake=emergency_brake,
        )
        dynamics = self.dynamics
        if isinstance(dynamics, BogiePlant):
            if not isinstance(demand, ActuatorCommands):
                raise TypeError("the bogie model is driven by the VCU's actuator commands")
            dynamics.step(step, demand)
        else:
            if isinstance(demand, ActuatorCommands):
                raise TypeError("the point-mass model is driven by a force demand")
            dynamics.step(
                dt_s,
                demand,
                gradient_permille=step.gradient_permille,
                curve_radius_m=step.curve_radius_m,
                emergency_brake=emergency_brake,
            )
        self.time_s = now_s
        self._sample()

    def _sample(self) -> None:
        truth = self.truth
        if self.interface_modules is not None:
            self._datagrams.extend(self.interface_modules.step(truth))
        if self.wheel_sensors is not None:
            self.wheels = self.wheel_sensors.step(self._wheel_truth(truth))
            self._wheel_readings.append(self.wheels)
        if self.balise_reader is not None:
            self._balises.extend(self.balise_reader.step(truth.time_s, truth.position_m))
        if self.marker_reader is not None:
            self._markers.extend(self.marker_reader.step(truth.time_s, truth.position_m))

    def _wheel_truth(self, truth: TruthSample) -> BogieTruth | TruthSample:
        """Each wheel's rotation on the bogie model; the body's travel on the point mass."""
        return self.dynamics.truth if isinstance(self.dynamics, BogiePlant) else truth

    # -- the sensors' outputs ------------------------------------------------------------------

    def take_datagrams(self) -> list[bytes]:
        """The interface-modules' INPUT datagrams sent since the last call."""
        datagrams, self._datagrams = self._datagrams, []
        return datagrams

    def take_wheel_readings(self) -> list[WheelReading]:
        """The axle-end sensors' readings since the last call, oldest first."""
        readings, self._wheel_readings = self._wheel_readings, []
        return readings

    def take_balise_detections(self) -> list[BaliseDetection]:
        """The balise groups the BTM located since the last call, oldest first."""
        detections, self._balises = self._balises, []
        return detections

    def take_marker_detections(self) -> list[MarkerDetection]:
        """The stop markers the marker reader located since the last call, oldest first."""
        detections, self._markers = self._markers, []
        return detections

    @property
    def drive(self) -> DriveReading:
        return drive_reading(self.dynamics, self.time_s)

    def powertrain_reading(self) -> PowertrainReading | None:
        """The BMS's, range extender's and drives' reports (the bogie model's powertrain)."""
        if isinstance(self.dynamics, BogiePlant):
            return self.dynamics.powertrain_reading()
        return None

    def force_limits_n(self, speed_mps: float) -> tuple[float, float]:
        return force_limits_n(self.dynamics, speed_mps)
