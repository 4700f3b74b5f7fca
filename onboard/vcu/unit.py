"""The vehicle control unit (VCU) of seed 003 §3: from a demand to actuator references.

Each step the VCU takes a longitudinal force demand at the rail [N] from the ADF (or a speed
reference, tracked by its own PI loop), reads the powertrain's feedback, and returns
:class:`~onboard.plant.interfaces.ActuatorCommands`: motor torques per axle, brake cylinder
pressures, the range extender's power reference. The strategies live in ``traction``,
``braking`` and ``limits``; this module wires them and records a :class:`VcuStatus`.
"""

from __future__ import annotations

from onboard.plant.interfaces import ActuatorCommands
from onboard.vcu.braking import BlendedBraking
from onboard.vcu.limits import BatteryOverload, EnergyManager, SlipperyRail, temperature_factor
from onboard.vcu.parameters import BrakingPhase, Limitation, VcuInputs, VcuParameters, VcuStatus
from onboard.vcu.traction import AxleSlipProtection, TorqueSplit, motor_torque_limit_nm

__all__ = ["SpeedLoop", "VehicleControlUnit"]

MIN_POWER_SPEED_MPS = 1.0
"""Below this speed the power limits give way to the torque limits (ω → 0)."""
BATTERY_EFFICIENCY = 0.95
"""The packs' efficiency (seed 003 §6.1): terminal power = η × cell power when discharging."""


class SpeedLoop:
    """PI from speed error [m/s] to force demand [N] with a clamped integral (anti-windup)."""

    def __init__(self, parameters: VcuParameters, *, max_force_n: float, min_force_n: float):
        self.parameters = parameters
        self.max_force_n = max_force_n
        self.min_force_n = min_force_n
        self.integral_n = 0.0

    def step(self, dt_s: float, reference_mps: float, speed_mps: float) -> float:
        p = self.parameters
        error = reference_mps - speed_mps
        self.integral_n += p.speed_ki_n_per_m * error * dt_s
        self.integral_n = min(max(self.integral_n, self.min_force_n), self.max_force_n)
        force = p.speed_kp_n_per_mps * error + self.integral_n
        return min(max(force, self.min_force_n), self.max_force_n)


class VehicleControlUnit:
    """Torque split, slip protection, blended braking, limitations and energy management."""

    def __init__(self, parameters: VcuParameters | None = None) -> None:
        p = parameters if parameters is not None else VcuParameters()
        self.parameters = p
        max_traction_n = 2.0 * p.max_motor_torque_nm / p.wheel_radius_m
        max_brake_n = 2.0 * p.brake_gain_nm_per_pa * p.max_brake_pressure_pa / p.wheel_radius_m
        self.speed_loop = SpeedLoop(p, max_force_n=max_traction_n, min_force_n=-max_brake_n)
        self.torque_split = TorqueSplit(p)
        self.braking = BlendedBraking(p)
        self.slip_front = AxleSlipProtection(p)
        self.slip_rear = AxleSlipProtection(p)
        self.overload = BatteryOverload(p)
        self.slippery_rail = SlipperyRail(p)
        self.energy = EnergyManager(p)
        self.commands = ActuatorCommands()
        self.status = VcuStatus()

    def step(self, dt_s: float, inputs: VcuInputs) -> ActuatorCommands:
        """Advance by ``dt_s`` [s] with this step's inputs; return the actuator references."""
        p = self.parameters
        force = inputs.force_demand_n
        if inputs.speed_reference_mps is not None:
            force = self.speed_loop.step(dt_s, inputs.speed_reference_mps, inputs.fused_speed_mps)
        limitations: set[Limitation] = set()
        slips = self._detect_slips(dt_s, inputs)
        overloaded = self.overload.step(dt_s, inputs.battery_current_a, inputs.continuous_current_a)
        range_extender_w = self.energy.step(
            dt_s,
            soc=inputs.soc,
            bus_load_w=self._drives_power_w(inputs) + p.auxiliary_power_w,
            max_discharge_w=inputs.max_discharge_power_w,
            battery_overloaded=overloaded,
            continuous_discharge_w=self._continuous_discharge_w(inputs),
        )
        allowance_w = self._battery_allowance_w(inputs, overloaded, limitations)
        traction_limit_w = max(
            allowance_w + inputs.range_extender_power_w - p.auxiliary_power_w, 0.0
        )
        torque = force * p.wheel_radius_m
        if torque >= 0.0:
            front, rear, pressure = self._traction(torque, inputs, traction_limit_w, limitations)
            phase, electric, pneumatic = BrakingPhase.NONE, 0.0, 0.0
        else:
            split = self.braking.split(
                -torque,
                speed_mps=inputs.fused_speed_mps,
                wheel_speeds_radps=(inputs.wheel_speed_front_radps, inputs.wheel_speed_rear_radps),
                soc=inputs.soc,
                max_regen_power_w=self._max_regen_mechanical_w(inputs),
            )
            if split.limited_by_soc:
                limitations.add(Limitation.HIGH_SOC)
            phase, electric, pneumatic = split.phase, split.electric_nm, split.pneumatic_nm
            front = rear = -0.5 * electric * inputs.direction
            pressure = 0.5 * pneumatic / p.brake_gain_nm_per_pa
        self.commands = ActuatorCommands(
            motor_torque_front_nm=front,
            motor_torque_rear_nm=rear,
            brake_pressure_front_pa=pressure,
            brake_pressure_rear_pa=pressure,
            range_extender_power_w=range_extender_w,
        )
        self.status = VcuStatus(
            braking_phase=phase,
            slip_front=slips[0],
            slip_rear=slips[1],
            limitations=frozenset(limitations),
            range_extender_on=self.energy.range_extender_on,
            force_demand_n=force,
            electric_braking_torque_nm=electric,
            pneumatic_braking_torque_nm=pneumatic,
            traction_power_limit_w=traction_limit_w,
        )
        return self.commands

    def _detect_slips(self, dt_s: float, inputs: VcuInputs) -> tuple[bool, bool]:
        """Run both axles' slip protection; feed slip onsets to the slippery-rail logic."""
        radius = self.parameters.wheel_radius_m
        front_mps = abs(inputs.wheel_speed_front_radps) * radius
        rear_mps = abs(inputs.wheel_speed_rear_radps) * radius
        vehicle = inputs.fused_speed_mps
        slip_front = self.slip_front.detects_slip(front_mps, vehicle, rear_mps)
        slip_rear = self.slip_rear.detects_slip(rear_mps, vehicle, front_mps)
        onsets = int(slip_front and not self.slip_front.slipping)
        onsets += int(slip_rear and not self.slip_rear.slipping)
        self.slip_front.step(dt_s, slip_front, self.commands.motor_torque_front_nm)
        self.slip_rear.step(dt_s, slip_rear, self.commands.motor_torque_rear_nm)
        self.slippery_rail.step(dt_s, onsets)
        return slip_front, slip_rear

    def _drives_power_w(self, inputs: VcuInputs) -> float:
        """Electrical power [W] of the drives under the last commanded torques."""
        c, eta = self.commands, self.parameters.drive_efficiency
        mechanical = c.motor_torque_front_nm * inputs.wheel_speed_front_radps * inputs.direction
        mechanical += c.motor_torque_rear_nm * inputs.wheel_speed_rear_radps * inputs.direction
        return mechanical / eta if mechanical >= 0.0 else mechanical * eta

    def _battery_allowance_w(
        self, inputs: VcuInputs, overloaded: bool, limitations: set[Limitation]
    ) -> float:
        """Discharge power [W] the VCU lets the drives draw from the batteries."""
        allowance = min(inputs.max_discharge_power_w, self.energy.battery_allowance_w)
        if self.energy.sustaining or inputs.max_discharge_power_w <= 0.0:
            limitations.add(Limitation.LOW_SOC)
        if overloaded:
            limitations.add(Limitation.BATTERY_OVERLOAD)
            allowance = min(allowance, self._continuous_discharge_w(inputs))
        return allowance

    @staticmethod
    def _continuous_discharge_w(inputs: VcuInputs) -> float:
        """Terminal power [W] of the packs at their continuous (I²T) current rating."""
        return inputs.continuous_current_a * inputs.battery_voltage_v * BATTERY_EFFICIENCY

    def _max_regen_mechanical_w(self, inputs: VcuInputs) -> float:
        """Mechanical braking power [W] the drives may take without overcharging the batteries."""
        p = self.parameters
        electrical = inputs.max_charge_power_w + p.auxiliary_power_w - inputs.range_extender_power_w
        return max(electrical, 0.0) / p.drive_efficiency

    def _axle_limits_nm(
        self, inputs: VcuInputs, limitations: set[Limitation]
    ) -> tuple[float, float]:
        """Traction torque limits [N·m] of the (front, rear) axles."""
        p = self.parameters
        slippery = 1.0
        if self.slippery_rail.active:
            slippery = p.slippery_rail_torque_fraction
            limitations.add(Limitation.SLIPPERY_RAIL)
        limits = []
        for omega, temperature, slip in (
            (inputs.wheel_speed_front_radps, inputs.motor_temperature_front_c, self.slip_front),
            (inputs.wheel_speed_rear_radps, inputs.motor_temperature_rear_c, self.slip_rear),
        ):
            thermal = temperature_factor(temperature, p)
            if thermal < 1.0:
                limitations.add(Limitation.TEMPERATURE)
            curve = motor_torque_limit_nm(omega, p) * thermal * slippery
            limits.append(min(curve, slip.torque_limit_nm))
        return limits[0], limits[1]

    def _traction(
        self,
        torque_nm: float,
        inputs: VcuInputs,
        traction_limit_w: float,
        limitations: set[Limitation],
    ) -> tuple[float, float, float]:
        """(front, rear) motor torques [N·m] with direction sign, and brake pressure 0 [Pa]."""
        p = self.parameters
        speed = max(inputs.fused_speed_mps, MIN_POWER_SPEED_MPS)
        power_torque = traction_limit_w * p.drive_efficiency * p.wheel_radius_m / speed
        if torque_nm > power_torque:
            limitations.add(Limitation.POWER)
            torque_nm = power_torque
        front_limit, rear_limit = self._axle_limits_nm(inputs, limitations)
        forwards = inputs.direction >= 0
        trailing_limit, leading_limit = (
            (rear_limit, front_limit) if forwards else (front_limit, rear_limit)
        )
        axles = self.torque_split.split(
            torque_nm, inputs.fused_speed_mps, (trailing_limit, leading_limit)
        )
        sign = 1.0 if forwards else -1.0
        if forwards:
            return sign * axles.leading_nm, sign * axles.trailing_nm, 0.0
        return sign * axles.trailing_nm, sign * axles.leading_nm, 0.0
