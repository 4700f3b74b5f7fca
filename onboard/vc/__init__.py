"""The Vital Control module (seeds 001, 004; DOMAIN.md §7.2): a pure, deterministic library.

The VC is the GoA4 vehicle's extra protection: it checks every 40 ms that the ATO-OB is alive
and the remote operator vigilant, supervises speed and odometry when ETCS is isolated, switches
ETCS off and on by a radio relay, applies the emergency brake by de-energising the solenoid
valves, rearms it only when safe and confirmed, and enters System Decay when recovery would not
be safe. Three tasks on the executive, sharing no mutable state:

- :mod:`~onboard.vc.task_a`: Task A (40 ms), composes the request to the ATO-OB;
- :mod:`~onboard.vc.task_b`: Task B (2 ms, highest priority), checks the responses, the
  deadlines, the odometry (:mod:`~onboard.vc.odometry`) and the digital inputs, raises the EB
  flag and System Decay;
- :mod:`~onboard.vc.task_c`: Task C (2 ms, after B), drives the valves and the relay;
- :mod:`~onboard.vc.redundancy`: two replicas in 2-out-of-2 and their watchdogs;
  :mod:`~onboard.vc.datalog`: the black box (JSON Lines) and its reader;
- :mod:`~onboard.vc.installation`: the VC as fitted to a vehicle, its I/O wired to the plant,
  the ETCS onboard and the BTM;
- :mod:`~onboard.vc.quiet`: in lockstep, B and C skip the cycles that cannot change them;
- :mod:`~onboard.vc.fsm`: their transition tables; :mod:`~onboard.vc.ipc`: their mailboxes and
  messages; :mod:`~onboard.vc.module`: :class:`VitalControl`, which wires and registers them.

Around them: the request/response messages (:mod:`~onboard.vc.messages`), the fault-injectable
link (:mod:`~onboard.vc.link`) and the emulated I/O (:mod:`~onboard.vc.hardware`). The test
double of the ATO-OB, the scenario catalogue, its lockstep runner and the fused-speed comparison
drive and score the VC from outside; they are in ``deploy.bench`` (``vc_responder``,
``vc_scenarios``, ``vc_catalogue``, ``vc_runner``, ``vc_fused_speed``). Parameters are in
:class:`VcConfig` (:mod:`~onboard.vc.config`); errors in :mod:`onboard.vc._exceptions`.

No Zenoh, no threads, no wall clock: every call takes ``now_s``. docs/vc.md describes the
model and the choices.

Abbreviations: VC (vital control), ATO-OB / ATO-TS (ATO onboard / trackside), EB (emergency
brake), ETCS-OB (the ETCS onboard), BTM (balise transmission module), ATO-ODO (the odometry
board), FSM (finite state machine), IPC (inter-process communication).
"""

from onboard.vc._exceptions import (
    VcError,
    VcInputError,
)
from onboard.vc.config import (
    TIME_TOLERANCE_S,
    VcConfig,
)
from onboard.vc.datalog import (
    DATALOG_PRIORITY,
    Datalog,
    DatalogCorruptError,
    DatalogRecord,
    DatalogRecorder,
    DatalogReplay,
    read_datalog,
)
from onboard.vc.exchange_check import (
    CONFIRMED_SECTIONS,
    ExchangeCheck,
    Findings,
)
from onboard.vc.fsm import (
    ALL_TABLES,
    TASK_A_TRANSITIONS,
    TASK_B_TRANSITIONS,
    TASK_C_BRAKE_TRANSITIONS,
    TASK_C_ETCS_TRANSITIONS,
    BrakeState,
    EtcsState,
    Fsm,
    FsmCoverage,
    FsmTransition,
    StateMachine,
    TaskAState,
    TaskBState,
    TransitionRule,
    Trigger,
    select_rule,
    transition_coverage,
)
from onboard.vc.hardware import (
    FRAME_NUMBER_MODULO,
    FULL_EB_DELAY_S,
    RECHARGE_S,
    RELAY_SWITCHING_DELAY_S,
    RELEASE_FRACTION,
    EmergencyBrakeValves,
    PipeFault,
    RadioRelay,
    RelayFault,
    TachometerBoard,
    TachometerFault,
    TachometerFaultMode,
    TachometerFrame,
    ValveCommand,
)
from onboard.vc.installation import (
    IO_PRIORITY,
    VcFaults,
    VcInstallation,
)
from onboard.vc.ipc import (
    ActuationStatus,
    Delivery,
    Mailbox,
    MessageQueue,
    SupervisionStatus,
    VcEvent,
    VcEventKind,
)
from onboard.vc.link import (
    FaultyLink,
    LinkDirection,
    LinkFault,
    LinkFaultKind,
    corrupt_response,
)
from onboard.vc.messages import (
    DECAY_CONDITIONS,
    PULSED_SECTIONS,
    SECTIONS,
    AtoObResponse,
    AtoObStatus,
    DecayReason,
    EbCondition,
    Notification,
    Section,
    SectionRequest,
    SectionResponse,
    VcRequest,
    expected_response_number,
)
from onboard.vc.module import (
    TASK_A_PRIORITY,
    TASK_B_PRIORITY,
    TASK_C_PRIORITY,
    VcHardware,
    VcOutputs,
    VitalControl,
)
from onboard.vc.odometry import (
    MAX_FRAME_GAP,
    OdometryEstimate,
    TachometerOdometry,
)
from onboard.vc.quiet import (
    QuietCycles,
    skips_quiet_cycles,
)
from onboard.vc.redundancy import (
    VOTER_PRIORITY,
    PairEvent,
    PairEventKind,
    RedundancyConfig,
    ReplicaFault,
    ReplicaFaultKind,
    ReplicaView,
    TwoOutOfTwo,
    Watchdog,
)
from onboard.vc.task_a import (
    TaskA,
)
from onboard.vc.task_b import (
    TaskB,
)
from onboard.vc.task_c import (
    TaskC,
)
from onboard.vc.tick import (
    Doorbell,
    QuietTick,
)

__all__ = [
    "ALL_TABLES",
    "IO_PRIORITY",
    "VcFaults",
    "VcInstallation",
    "CONFIRMED_SECTIONS",
    "ExchangeCheck",
    "Findings",
    "DATALOG_PRIORITY",
    "DECAY_CONDITIONS",
    "FRAME_NUMBER_MODULO",
    "FULL_EB_DELAY_S",
    "MAX_FRAME_GAP",
    "PULSED_SECTIONS",
    "RECHARGE_S",
    "RELAY_SWITCHING_DELAY_S",
    "RELEASE_FRACTION",
    "SECTIONS",
    "TASK_A_PRIORITY",
    "TASK_A_TRANSITIONS",
    "TASK_B_PRIORITY",
    "TASK_B_TRANSITIONS",
    "TASK_C_BRAKE_TRANSITIONS",
    "TASK_C_ETCS_TRANSITIONS",
    "TASK_C_PRIORITY",
    "TIME_TOLERANCE_S",
    "VOTER_PRIORITY",
    "ActuationStatus",
    "AtoObResponse",
    "AtoObStatus",
    "BrakeState",
    "Datalog",
    "DatalogCorruptError",
    "Doorbell",
    "DatalogRecord",
    "DatalogRecorder",
    "DatalogReplay",
    "DecayReason",
    "Delivery",
    "EbCondition",
    "EmergencyBrakeValves",
    "EtcsState",
    "FaultyLink",
    "Fsm",
    "FsmCoverage",
    "FsmTransition",
    "LinkDirection",
    "LinkFault",
    "LinkFaultKind",
    "Mailbox",
    "MessageQueue",
    "Notification",
    "OdometryEstimate",
    "PairEvent",
    "PairEventKind",
    "PipeFault",
    "QuietCycles",
    "QuietTick",
    "RadioRelay",
    "RedundancyConfig",
    "RelayFault",
    "ReplicaFault",
    "ReplicaFaultKind",
    "ReplicaView",
    "Section",
    "SectionRequest",
    "SectionResponse",
    "StateMachine",
    "SupervisionStatus",
    "TachometerBoard",
    "TachometerFault",
    "TachometerFaultMode",
    "TachometerFrame",
    "TachometerOdometry",
    "TaskA",
    "TaskAState",
    "TaskB",
    "TaskBState",
    "TaskC",
    "TransitionRule",
    "Trigger",
    "TwoOutOfTwo",
    "ValveCommand",
    "VcConfig",
    "VcError",
    "VcEvent",
    "VcEventKind",
    "VcHardware",
    "VcInputError",
    "VcOutputs",
    "VcRequest",
    "VitalControl",
    "Watchdog",
    "corrupt_response",
    "expected_response_number",
    "read_datalog",
    "select_rule",
    "skips_quiet_cycles",
    "transition_coverage",
]
