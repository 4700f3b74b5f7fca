"""The ATO-OB controller (SUBSET-125 §9; DOMAIN.md §2.1): a pure, deterministic library.

The controller of the ATO-OB (seed 000's "main ATO FSM", DOMAIN.md §7.1) decides whether the ATO
may drive: it checks the configuration, operational and engagement conditions, takes the
operator's engage and disengage, supervises the ETCS-OB link, and tells the ADF which mode to be
in, whether it may use traction, and which ETCS limits to respect.

Modules, each citing the DOMAIN.md section it follows:

- :mod:`~onboard.ato_ob.conditions`: the inputs and the named conditions (§2.1, §7.1);
- :mod:`~onboard.ato_ob.transitions`: the states' transition table (§2.1);
- :mod:`~onboard.ato_ob.controller`: :class:`AtoObController`, which ties them together, and
  the GoA4 choices (§3; docs/ato_ob.md).

No Zenoh, no threads, no wall clock: every call takes ``now_s``. The errors are listed in one
place, :mod:`onboard.ato_ob._exceptions`, and re-exported here.

Abbreviations: ATO-OB / ATO-TS (ATO onboard / trackside), ADF (autonomous driving function),
JP (journey profile), MA (movement authority), EoA (end of authority), SvL (supervised location),
EB (emergency brake), GoA (grade of automation); the states NP (no power), CO (configuration),
NA (not available), AV (available), RE (ready), EG (engaged), DE (disengaging), FA (failure);
the ETCS modes FS (full supervision) and AD (automatic driving).
"""

from onboard.ato_ob._exceptions import AtoObError, AtoObInputError, RequestRefusedError
from onboard.ato_ob.conditions import (
    CONFIGURATION_CONDITIONS,
    ENGAGEMENT_CONDITIONS,
    OPERATIONAL_CONDITIONS,
    AtoObInputs,
    Condition,
    EtcsStatus,
)
from onboard.ato_ob.controller import (
    AUTOMATIC_DRIVING_ENTRY_S,
    DISENGAGING_S,
    ETCS_LINK_TIMEOUT_S,
    FAILURE_WARNING_S,
    AtoObController,
    AtoObOutput,
    AtoTransition,
)
from onboard.ato_ob.transitions import ATO_OB_TRANSITIONS, TransitionRule, Trigger

__all__ = [
    "ATO_OB_TRANSITIONS",
    "AUTOMATIC_DRIVING_ENTRY_S",
    "CONFIGURATION_CONDITIONS",
    "DISENGAGING_S",
    "ENGAGEMENT_CONDITIONS",
    "ETCS_LINK_TIMEOUT_S",
    "FAILURE_WARNING_S",
    "OPERATIONAL_CONDITIONS",
    "AtoObController",
    "AtoObError",
    "AtoObInputError",
    "AtoObInputs",
    "AtoObOutput",
    "AtoTransition",
    "Condition",
    "EtcsStatus",
    "RequestRefusedError",
    "TransitionRule",
    "Trigger",
]
