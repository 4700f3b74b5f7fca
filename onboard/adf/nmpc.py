"""The autonomous-driving (AD) controller of seed 000: nonlinear model predictive control.

Over a horizon of N steps of ``step_s`` it minimises

    Σ ω1 (p − p_ref)² + ω2 (v − v_ref)² + ω3 u² + ω4 Δu²

subject to the control-oriented model M(1 + ρ) v̇ = F − (γ + η v + ι v²) − F_track, ṗ = v,
τ Ḟ = u − F (F_track: gradient and curve forces along the reference, given per stage; F the force
the actuators apply, which follows the demand u with the first-order lag τ of the vehicle's
parameters), v_min ≤ v ≤ v_max(p), −F_brake ≤ u ≤ F_max and u·v ≤ P_max (the traction power).
The demand u and the applied force F are carried in the state and the decision variables are the
increments Δu (multiple shooting, one RK4 step per interval). Without the lag in the model a
braking phase of a few seconds, as at the end of a coasting leg, starts τ late and overshoots the
stop by about τ·v. The NLP is built once with casadi and solved by ``sqpmethod`` with the
``qrqp`` QP solver, warm-started from the previous solution shifted by one step, its
multipliers as well, so that qrqp starts from the last active set (from a rollout of the model
when cold, and when the reference or the ceiling jumps: a TSR, a replanned leg, a new permitted
speed); IPOPT can be chosen for comparison. The solver is called through casadi's buffers
(:mod:`onboard.adf.nlp_call`).

The solve time is bounded by construction: at most ``max_iterations`` SQP iterations
(``max_cold_iterations`` from a cold start) of at most ``max_qp_iterations`` QP iterations
each. Near an active constraint (cruising just under a ceiling) the SQP's primal residual can
stall at about 1e-5 without meeting a tighter tolerance, so the tolerances are 1e-4 in the
NLP's units (m, m/s, kN: a tenth of a millimetre, of a mm/s, of a newton); an iterate that did
not converge but meets every constraint within 1e-2 is used (counted as not converged).
Otherwise the step falls back to a safe control law, counted as a failure: full service braking
above the ceiling, else a proportional speed law onto the lower of the reference and the
ceiling, with the resistance and track forces fed forward; its demand changes at most by the
NMPC's own rate bound a step.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Any, Literal

import casadi as ca
import numpy as np
import numpy.typing as npt

from onboard.adf.nlp_call import BufferedNlp
from onboard.plant.point_mass import MIN_POWER_SPEED_MPS, PointMassParameters

__all__ = ["NmpcConfig", "NmpcController", "NmpcReference", "NmpcResult", "NmpcStats"]

FloatArray = npt.NDArray[np.float64]
STATE_SIZE = 4
"""p (relative to the measured one) [m], v [m/s], applied force F [kN], demand u [kN]."""
MAX_SPEED_MPS = 100.0
KN = 1000.0
"""Forces are in kN inside the NLP and positions relative to the measured one: a well-scaled
problem converges in a few SQP iterations even from a cold start."""


@dataclass(frozen=True, kw_only=True)
class NmpcConfig:
    horizon_steps: int = 50
    step_s: float = 0.2
    weight_position: float = 1.0
    """ω1 [1/m²]"""
    weight_speed: float = 10.0
    """ω2 [s²/m²]"""
    weight_force: float = 1e-8
    """ω3 [1/N²]"""
    weight_force_rate: float = 1e-6
    """ω4 [1/N²] on the increment per step"""
    max_force_step_n: float = 3_000.0
    """Largest change of u in one step [N]: with 0.2 s steps and the URV's 16 t, about
    0.9 m/s³ of jerk."""
    min_predicted_speed_mps: float = -1.0
    """Lower bound on predicted speed [m/s]. The smooth model lets a braked vehicle reverse,
    where the real one stops; a hard v ≥ 0 would make stopping on the brake infeasible within
    the force-rate bound, so a small negative predicted speed stands for standing still."""
    solver: Literal["sqpmethod", "ipopt"] = "sqpmethod"
    max_iterations: int = 3
    """SQP iterations of a warm-started solve, which takes one: cruising or accelerating just
    under a ceiling the primal residual can stall near 1e-3 from the first iteration on, and
    further iterations change the demand by less than a newton."""
    max_cold_iterations: int = 6
    """SQP iterations of a solve started cold (from a rollout of the model): one or two on the
    ADF's references, up to six with a reference above the ceiling and the power limit
    binding."""
    max_qp_iterations: int = 50
    """QP iterations in each SQP iteration (qrqp)."""
    tolerance: float = 1e-4
    """Primal and dual tolerance of the SQP, in the NLP's units (m, m/s, kN)."""
    feasibility_tolerance: float = 1e-2
    """Largest constraint violation of a non-converged iterate that is still used (in the NLP's
    units: 1 cm/s over a ceiling somewhere in the horizon, 10 N of a dynamics defect); only its
    first step is applied, and the next solve starts from the measured state again."""
    jump_mps: float = 1.0
    """A reference or ceiling that differs from the previous one (shifted a step) by more than
    this at some stage is a jump: the next solve starts cold."""
    fallback_gain_per_s: float = 0.5
    """The fallback law's speed gain: the acceleration demanded per m/s of speed error [1/s]."""


@dataclass(frozen=True)
class NmpcReference:
    """Per-stage reference over the horizon, each of length ``horizon_steps``."""

    position_m: FloatArray
    speed_mps: FloatArray
    max_speed_mps: FloatArray
    track_force_n: FloatArray


@dataclass(frozen=True)
class NmpcResult:
    force_n: float
    """Force to apply over the next step [N]."""
    success: bool
    fallback: bool
    solve_time_s: float
    predicted_speed_mps: FloatArray
    predicted_force_n: FloatArray


@dataclass
class NmpcStats:
    solves: int = 0
    failures: int = 0
    """Solves whose step was the fallback law's."""
    not_converged: int = 0
    """Solves that hit an iteration cap with a feasible iterate, which was used."""
    cold_starts: int = 0
    """Solves started from a rollout: after a reset, a failure or a jump of the reference."""
    solve_times_s: list[float] = field(default_factory=list)


class NmpcController:
    """Receding-horizon speed and position tracking for the point-mass model."""

    def __init__(self, model: PointMassParameters, config: NmpcConfig | None = None) -> None:
        self.model = model
        self.config = config or NmpcConfig()
        self.stats = NmpcStats()
        self._step = self._dynamics()
        self._rollout = self._rollout_function()
        problem, bounds = self._build()
        self._upper_x = bounds["ubx"]
        # One NLP, two iteration caps: casadi fixes a solver's options when it is made.
        self._solver, self._cold_solver = (
            BufferedNlp(
                ca.nlpsol("nmpc", self.config.solver, problem, _solver_options(self.config, cap))
            )
            for cap in (self.config.max_iterations, self.config.max_cold_iterations)
        )
        for solver in (self._solver, self._cold_solver):
            solver(**bounds)  # the constant bounds, set once (a solve of zeros, discarded)
        n = self.config.horizon_steps
        self._guess: FloatArray | None = None
        stride = STATE_SIZE + 1
        self._variables = stride * n + STATE_SIZE
        self._state_index = stride * np.arange(n + 1)[:, None] + np.arange(STATE_SIZE)
        """Where each stage's state lies among the variables, (n + 1, 4)."""
        self._increment_index = stride * np.arange(n) + STATE_SIZE
        self._multipliers: tuple[FloatArray, FloatArray] | None = None
        """The last solution's multipliers of the bounds and of the constraints."""
        self._shift_bounds, self._shift_constraints = _stage_shifts(n)
        self._demand_n: float | None = None
        self._reference: NmpcReference | None = None

    def _dynamics(self) -> ca.Function:
        m = self.model
        dt = self.config.step_s
        state, increment, track = ca.SX.sym("x", STATE_SIZE), ca.SX.sym("du"), ca.SX.sym("ft")
        mass = m.mass_kg * (1.0 + m.rotating_mass_factor)

        lag_s = m.actuator_time_constant_s

        def rate(x: Any) -> Any:
            v, applied = x[1], x[2] * KN
            resistance = m.davis_a_n + m.davis_b_n_per_mps * v + m.davis_c_n_per_mps2 * v * v
            following = (x[3] - x[2]) / lag_s if lag_s > 0 else 0
            return ca.vertcat(v, (applied - resistance - track * KN) / mass, following, 0)

        demand = state[3] + increment
        applied = state[2] if lag_s > 0 else demand
        start = ca.vertcat(state[0], state[1], applied, demand)
        k1 = rate(start)
        k2 = rate(start + dt / 2 * k1)
        k3 = rate(start + dt / 2 * k2)
        k4 = rate(start + dt * k3)
        end = start + dt / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
        return ca.Function("step", [state, increment, track], [end])

    def _rollout_function(self) -> ca.Function:
        """The cold start's guess: the model run over the horizon with the demand held, its
        speed kept within the predicted speeds' bounds at each step; (x0, track forces [kN],
        1 × N) → the states after each step (4 × N). One call: a loop of N calls of the step
        took 2.7 ms, most of a cold solve."""
        state, track = ca.SX.sym("x", STATE_SIZE), ca.SX.sym("ft")
        low, high = self.config.min_predicted_speed_mps, MAX_SPEED_MPS
        end = self._step(state, 0.0, track)
        held = ca.vertcat(end[0], ca.fmin(ca.fmax(end[1], low), high), end[2], end[3])
        stage = ca.Function("rolled", [state, track], [held])
        return stage.mapaccum("rollout", self.config.horizon_steps)

    def _build(self) -> tuple[dict[str, Any], dict[str, FloatArray]]:
        """The NLP (for ``ca.nlpsol``) and its bounds, stage by stage: the variables
        [x0, Δu0, x1, Δu1, ..., x_N] and the constraints [gap0, x0 − x̂, gap1, power1, ...,
        power_N]. In this order the QP's KKT matrix is banded, and qrqp's sparse QR of it
        fills in little: a solve took a quarter less time than with all states first, then
        all increments."""
        c, m, n = self.config, self.model, self.config.horizon_steps
        step = self._step
        states = ca.SX.sym("X", STATE_SIZE, n + 1)
        increments = ca.SX.sym("dU", 1, n)
        parameters = ca.SX.sym("P", STATE_SIZE + 3 * n)
        s = STATE_SIZE
        p_ref, v_ref = parameters[s : s + n], parameters[s + n : s + 2 * n]
        track = parameters[s + 2 * n :]
        cost: Any = 0
        constraints: list[Any] = []
        lower: list[float] = []
        upper: list[float] = []
        variables: list[Any] = []
        power_kw = m.max_traction_power_w / KN
        for k in range(n):
            following = states[:, k + 1]
            variables += [states[:, k], increments[k]]
            constraints.append(following - step(states[:, k], increments[k], track[k]))
            lower += [0.0] * STATE_SIZE
            upper += [0.0] * STATE_SIZE
            if k == 0:
                constraints.append(states[:, 0] - parameters[0:s])
                lower += [0.0] * STATE_SIZE
                upper += [0.0] * STATE_SIZE
            else:
                constraints.append(states[3, k] * states[1, k])
                lower.append(-ca.inf)
                upper.append(power_kw)
            cost += (
                c.weight_position * (following[0] - p_ref[k]) ** 2
                + c.weight_speed * (following[1] - v_ref[k]) ** 2
                + c.weight_force * KN**2 * following[3] ** 2
                + c.weight_force_rate * KN**2 * increments[k] ** 2
            )
        variables.append(states[:, n])
        constraints.append(states[3, n] * states[1, n])
        lower.append(-ca.inf)
        upper.append(power_kw)
        problem: dict[str, Any] = {
            "x": ca.vertcat(*variables),
            "f": cost,
            "g": ca.vertcat(*constraints),
            "p": parameters,
        }
        bounds = {**self._variable_bounds(), "lbg": lower, "ubg": upper}
        return problem, {key: np.array(values, dtype=float) for key, values in bounds.items()}

    def _variable_bounds(self) -> dict[str, list[float]]:
        """The variables' bounds, [x0, Δu0, ..., x_N]: speed within the predicted range, the
        forces within the vehicle's, the demand's increment within a step."""
        c, m, n = self.config, self.model, self.config.horizon_steps
        forces = (-m.max_brake_force_n / KN, m.max_traction_force_n / KN)
        state_low = [-ca.inf, c.min_predicted_speed_mps, forces[0], forces[0]]
        state_high = [ca.inf, MAX_SPEED_MPS, forces[1], forces[1]]
        step_kn = c.max_force_step_n / KN
        return {
            "lbx": (state_low + [-step_kn]) * n + state_low,
            "ubx": (state_high + [step_kn]) * n + state_high,
        }

    def _stage_bounds(self, reference: NmpcReference) -> FloatArray:
        """The NLP's upper bounds of the variables with each stage's ceiling as the upper bound
        of its predicted speed.

        The ceiling is a bound, not a constraint row ``v − v_max ≤ 0``: beside the speed's own
        bounds such a row is a second, linearly dependent constraint on the same variable, and
        qrqp (an active-set method without anti-cycling) then cycles between the two (enforces
        one, drops the other for regularity) until its iteration cap wherever the optimum rides
        the ceiling over many stages, and the SQP's step leaves the ceiling violated."""
        upper = self._upper_x.copy()
        speeds = self._state_index[1:, 1]
        ceilings = np.minimum(reference.max_speed_mps, MAX_SPEED_MPS)
        upper[speeds] = np.maximum(ceilings, self.config.min_predicted_speed_mps)
        return upper

    def reset(self) -> None:
        """Forget the warm start and the previous plan (after a mode change)."""
        self._guess = None
        self._multipliers = None
        self._demand_n = None
        self._reference = None

    def note_demand(self, demand_n: float) -> None:
        """The demand [N] actually sent after the caller capped this controller's: the next
        step's rate bound starts from it."""
        self._demand_n = demand_n

    def solve(
        self,
        *,
        position_m: float,
        speed_mps: float,
        applied_force_n: float,
        reference: NmpcReference,
    ) -> NmpcResult:
        """One receding-horizon step from the measured state: position, speed and the force the
        actuators apply now; the demand starts from the last one this controller sent (the
        applied force after a reset)."""
        demand_n = applied_force_n if self._demand_n is None else self._demand_n
        state = np.array([0.0, max(speed_mps, 0.0), applied_force_n / KN, demand_n / KN])
        parameters = np.concatenate(
            [
                state,
                reference.position_m - position_m,
                reference.speed_mps,
                reference.track_force_n / KN,
            ]
        )
        upper = self._stage_bounds(reference)
        if self._reference is not None and _reference_jumped(
            reference, self._reference, self.config.jump_mps
        ):
            self._guess = None
        self._reference = reference
        started = time.perf_counter()
        solution = self._call_solver(state, parameters, upper, reference.track_force_n / KN)
        elapsed = time.perf_counter() - started
        self.stats.solves += 1
        self.stats.solve_times_s.append(elapsed)
        if solution is None:
            return self._fallback(elapsed, speed_mps, reference)
        values = solution["x"].copy()
        states = values[self._state_index]
        self._guess = values
        self._multipliers = (solution["lam_x"].copy(), solution["lam_g"].copy())
        forces_n = states[1:, 3] * KN
        self._demand_n = float(forces_n[0])
        return NmpcResult(
            force_n=float(forces_n[0]),
            success=True,
            fallback=False,
            solve_time_s=elapsed,
            predicted_speed_mps=states[1:, 1],
            predicted_force_n=forces_n,
        )

    def _call_solver(
        self, state: FloatArray, parameters: FloatArray, upper: FloatArray, track_kn: FloatArray
    ) -> dict[str, Any] | None:
        """The SQP from the warm start (the cold solver from a rolled-out guess when there is
        none); its solution, or None when it failed and its last iterate is not feasible."""
        solver = self._solver
        if self._guess is None:
            self.stats.cold_starts += 1
            solver = self._cold_solver
        try:
            guess = self._initial_guess(state, track_kn)
            lam_x: FloatArray | float = 0.0
            lam_g: FloatArray | float = 0.0
            if solver is self._solver and self._multipliers is not None:
                lam_x = self._multipliers[0][self._shift_bounds]
                lam_g = self._multipliers[1][self._shift_constraints]
            solution = solver(x0=guess, p=parameters, ubx=upper, lam_x0=lam_x, lam_g0=lam_g)
        except RuntimeError:
            return None
        if solver.success:
            return solution
        if _feasible(solver, self.config.feasibility_tolerance):
            self.stats.not_converged += 1
            return solution
        return None

    def _initial_guess(self, state: FloatArray, track_kn: FloatArray) -> FloatArray:
        n = self.config.horizon_steps
        if self._guess is None:
            # Cold start: the model rolled out with the demand held, so that the SQP starts
            # from a trajectory that meets the dynamics.
            guess = np.zeros(self._variables)
            rolled = np.asarray(self._rollout(state, track_kn[:n].reshape(1, -1)), dtype=float)
            rows = np.vstack([state, rolled.T])
            guess[self._state_index] = rows
            return guess
        states = self._guess[self._state_index]
        increments = self._guess[self._increment_index]
        states[:, 0] -= states[1, 0]  # the new origin is where the last plan's first step ends
        guess = np.empty(self._variables)
        guess[self._state_index] = np.vstack([state, states[2:], states[-1:]])
        guess[self._increment_index] = np.concatenate([increments[1:], [0.0]])
        return guess

    def _fallback(self, elapsed: float, speed_mps: float, reference: NmpcReference) -> NmpcResult:
        """The safe control law: full service braking above the ceiling, else a proportional
        speed law onto the lower of the reference and the ceiling, with the resistance and the
        track force fed forward; bounded by the brake, the traction force and power."""
        self.stats.failures += 1
        self._guess = None
        m, ceiling = self.model, float(reference.max_speed_mps[0])
        brake = -m.max_brake_force_n
        if speed_mps > ceiling:
            force = brake
        else:
            target = min(float(reference.speed_mps[0]), ceiling)
            mass = m.mass_kg * (1.0 + m.rotating_mass_factor)
            v = max(speed_mps, 0.0)
            resistance = m.davis_a_n + m.davis_b_n_per_mps * v + m.davis_c_n_per_mps2 * v * v
            force = (
                mass * self.config.fallback_gain_per_s * (target - speed_mps)
                + resistance
                + float(reference.track_force_n[0])
            )
            if target <= 0.0:
                force = min(force, 0.0) if speed_mps > 0.0 else brake
            traction = m.max_traction_force_n
            if v > MIN_POWER_SPEED_MPS:
                traction = min(traction, m.max_traction_power_w / v)
            force = min(max(force, brake), traction)
        if self._demand_n is not None:
            # At the NMPC's own rate bound, from its last demand: no jerk a solve would not make.
            step = self.config.max_force_step_n
            force = min(max(force, self._demand_n - step), self._demand_n + step)
        self._demand_n = force
        return NmpcResult(
            force_n=force,
            success=False,
            fallback=True,
            solve_time_s=elapsed,
            predicted_speed_mps=np.zeros(0),
            predicted_force_n=np.zeros(0),
        )


def _stage_shifts(n: int) -> tuple[npt.NDArray[np.intp], npt.NDArray[np.intp]]:
    """Where each multiplier of the next solve is taken from in the last one's: the bounds'
    (x_k, Δu_k from stage k + 1, the last stage's kept) and the constraints' ([gap0, x0 − x̂]
    from [gap1, x0 − x̂], gap_k, power_k from stage k + 1, the last gap kept, power_{n−1}
    and power_n from power_n)."""
    stride = STATE_SIZE + 1
    variables = stride * n + STATE_SIZE
    last_stage = np.arange(variables - stride - STATE_SIZE, variables)
    bounds = np.concatenate([np.arange(stride, variables), last_stage[-stride:]])
    first = 2 * STATE_SIZE  # stage 1's rows start after gap0 and x0 − x̂
    power_n = variables - 1
    last_gap = np.arange(power_n - stride, power_n - 1)
    constraints = np.concatenate(
        [
            np.arange(first, first + STATE_SIZE),
            np.arange(STATE_SIZE, first),
            np.arange(first + stride, power_n),
            last_gap,
            [power_n, power_n],
        ]
    )
    return bounds, constraints


def _solver_options(config: NmpcConfig, max_iterations: int) -> dict[str, Any]:
    if config.solver == "ipopt":
        return {
            "print_time": False,
            "ipopt.print_level": 0,
            "ipopt.sb": "yes",
            "ipopt.max_iter": max(max_iterations, 100),
        }
    return {
        "qpsol": "qrqp",
        # The power constraint u·v makes the Lagrangian's Hessian indefinite; qrqp needs a
        # convex QP, so negative eigenvalues are clipped.
        "convexify_strategy": "eigen-clip",
        "max_iter": max_iterations,
        "tol_pr": config.tolerance,
        "tol_du": config.tolerance,
        "print_header": False,
        "print_iteration": False,
        "print_time": False,
        "print_status": False,
        "error_on_fail": False,
        "qpsol_options": {
            "max_iter": config.max_qp_iterations,
            "print_iter": False,
            "print_header": False,
            "error_on_fail": False,
        },
    }


def _reference_jumped(reference: NmpcReference, previous: NmpcReference, jump_mps: float) -> bool:
    """Whether the reference or the ceiling moved by more than ``jump_mps`` against the
    previous one shifted by a step (the warm start would begin far from the new optimum)."""
    for new, old in (
        (reference.speed_mps, previous.speed_mps),
        (reference.max_speed_mps, previous.max_speed_mps),
    ):
        if np.any(
            np.abs(np.minimum(new[:-1], MAX_SPEED_MPS) - np.minimum(old[1:], MAX_SPEED_MPS))
            > jump_mps
        ):
            return True
    return False


def _feasible(solver: BufferedNlp, tolerance: float) -> bool:
    """Whether the solver's last solution meets every constraint and bound within
    ``tolerance``."""
    bounds, solution = solver.inputs, solver.outputs
    g, x = solution["g"], solution["x"]
    excess = max(
        float(np.max(bounds["lbg"] - g)),
        float(np.max(g - bounds["ubg"])),
        float(np.max(bounds["lbx"] - x)),
        float(np.max(x - bounds["ubx"])),
    )
    return bool(np.all(np.isfinite(x))) and excess <= tolerance
