"""The emulated ETCS onboard (SUBSET-026): a pure, deterministic library called with the time.

Modules, each citing the DOMAIN.md section it follows:

- :mod:`~onboard.etcs.values`: fixed values (A.3.1), national values (A.3.2), train data and
  the URV's (§1.1, §1.4, §1.5);
- :mod:`~onboard.etcs.deceleration`: A_safe and A_expected along the track, gradient included
  (§1.4);
- :mod:`~onboard.etcs.braking`: ceiling-speed margins, EBD, SBD, EBI, SBI1/2, W, P, I and the
  release speed (§1.1, §1.2);
- :mod:`~onboard.etcs.supervision`: CSM, TSM, RSM, statuses and commands (§1.3);
- :mod:`~onboard.etcs.modes`: the modes and their transition table (§1.6);
- :mod:`~onboard.etcs.movement_authority`: MA, EoA, SvL, timers, Levels 1 and 2 (§1.7);
- :mod:`~onboard.etcs.odometer`: the odometer on the wheel sensors: pulses, speed, A_est,
  slip and slide, and its accuracy law (§6);
- :mod:`~onboard.etcs.odometry`: the confidence interval, SUBSET-041's ±(5 m + 5 %·s) the
  bound (§6);
- :mod:`~onboard.etcs.balises`: balise groups read from the track database or the reader (§1.7);
- :mod:`~onboard.etcs.linking`: linked groups' expectation windows and Q_LINKREACTION (§1.6 [17]);
- :mod:`~onboard.etcs.localisation`: the odometer's position, the interval, the LRBG;
- :mod:`~onboard.etcs.onboard`: :class:`EtcsOnboard`, which ties them together through its
  parts: :mod:`~onboard.etcs.authority` (the MA in force and the track description),
  :mod:`~onboard.etcs.mode_control` (the mode, the level, the transitions),
  :mod:`~onboard.etcs.mode_supervision` (the supervision by mode, the commands latched) and
  :mod:`~onboard.etcs.balise_intake` (the groups read, the linking reactions); and
  :mod:`~onboard.etcs.output`: :class:`EtcsOutput`, what each cycle gives.

No Zenoh, no threads, no wall clock: every call takes ``now_s``. The errors are listed in one
place, :mod:`onboard.etcs._exceptions`, and re-exported here.

Abbreviations: MA (movement authority), EoA (end of authority), SvL (supervised location), LRBG
(last relevant balise group), MRSP (most restrictive speed profile), SSP (static speed profile),
EBD / SBD (emergency / service brake deceleration curves), EBI / SBI (emergency / service brake
intervention), W / P / I (warning, permitted, indication limits), CSM / TSM / RSM (ceiling,
target, release speed monitoring), EB / SB (emergency / service brake), RBC (radio block
centre), and the modes SB (stand-by), SR (staff responsible), FS (full supervision), OS (on
sight), AD (automatic driving), TR (trip), PT (post trip), IS (isolation).
"""

from onboard.etcs._exceptions import (
    BrakingCapabilityError,
    EtcsError,
    EtcsInputError,
    MovementAuthorityError,
    TrainDataError,
    TransitionRefusedError,
)
from onboard.etcs._motion import MotionSupervisor
from onboard.etcs.balises import BaliseGroupReading, TelegramHeader, read_balise_group
from onboard.etcs.braking import (
    BrakingCurve,
    BrakingModel,
    BrakingTimes,
    Limit,
    LimitDistances,
    Target,
    TargetKind,
    TargetLimits,
    braking_times,
    dv_ebi_mps,
    dv_sbi_mps,
    dv_warning_mps,
    speed_measurement_accuracy_mps,
)
from onboard.etcs.deceleration import DecelerationProfile
from onboard.etcs.linking import LinkingEvent, LinkingFault
from onboard.etcs.modes import MODE_TRANSITIONS, ModeChange, ModeCondition, ModeTransition
from onboard.etcs.movement_authority import (
    AuthorityInForce,
    EtcsLevel,
    MaChange,
    MaSection,
    MovementAuthority,
    OnSightArea,
)
from onboard.etcs.odometer import (
    URV_ODOMETER,
    Odometer,
    OdometerOutput,
    OdometerParameters,
    OdometerPosition,
    WheelAdhesion,
)
from onboard.etcs.odometry import (
    SUBSET_041_ACCURACY,
    ConfidenceInterval,
    Odometry,
    OdometryAccuracy,
)
from onboard.etcs.onboard import STANDSTILL_SPEED_MPS, EtcsOnboard
from onboard.etcs.output import EtcsOutput
from onboard.etcs.supervision import BrakeCommands, Monitoring, SupervisionResult
from onboard.etcs.values import (
    FIXED_VALUES,
    NATIONAL_DEFAULTS,
    URV_TRAIN_DATA,
    BrakeModelType,
    FixedValues,
    NationalValues,
    TrainData,
)

__all__ = [
    "FIXED_VALUES",
    "MODE_TRANSITIONS",
    "NATIONAL_DEFAULTS",
    "STANDSTILL_SPEED_MPS",
    "SUBSET_041_ACCURACY",
    "URV_ODOMETER",
    "URV_TRAIN_DATA",
    "AuthorityInForce",
    "BaliseGroupReading",
    "BrakeCommands",
    "BrakeModelType",
    "BrakingCapabilityError",
    "BrakingCurve",
    "BrakingModel",
    "BrakingTimes",
    "ConfidenceInterval",
    "DecelerationProfile",
    "EtcsError",
    "EtcsInputError",
    "EtcsLevel",
    "EtcsOnboard",
    "EtcsOutput",
    "FixedValues",
    "Limit",
    "LimitDistances",
    "LinkingEvent",
    "LinkingFault",
    "MaChange",
    "MaSection",
    "ModeChange",
    "ModeCondition",
    "ModeTransition",
    "Monitoring",
    "MotionSupervisor",
    "MovementAuthority",
    "MovementAuthorityError",
    "NationalValues",
    "Odometer",
    "OdometerOutput",
    "OdometerParameters",
    "OdometerPosition",
    "Odometry",
    "OdometryAccuracy",
    "OnSightArea",
    "SupervisionResult",
    "Target",
    "TargetKind",
    "TargetLimits",
    "TelegramHeader",
    "TrainData",
    "TrainDataError",
    "TransitionRefusedError",
    "WheelAdhesion",
    "braking_times",
    "dv_ebi_mps",
    "dv_sbi_mps",
    "dv_warning_mps",
    "read_balise_group",
    "speed_measurement_accuracy_mps",
]
