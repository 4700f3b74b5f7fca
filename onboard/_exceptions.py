"""The exception tree of the ``onboard`` package, in one place.

Every error the onboard raises on purpose derives from :class:`OnboardError`; each subpackage
keeps its own branch in its ``_exceptions`` module (documented there) and re-exports it::

    OnboardError (Exception)
    ├── AtoObError                         onboard.ato_ob: the ATO-OB controller
    │   ├── AtoObInputError (ValueError)
    │   └── RequestRefusedError
    ├── EtcsError                          onboard.etcs: the emulated ETCS onboard
    │   ├── EtcsInputError (ValueError)
    │   ├── TrainDataError (ValueError)
    │   ├── MovementAuthorityError (ValueError)
    │   ├── BrakingCapabilityError (ValueError)
    │   └── TransitionRefusedError
    ├── SfaError                           onboard.sfa: the sensor fusion
    │   ├── NotInitialisedError (RuntimeError)
    │   └── AddressError (ValueError)
    ├── VcError                            onboard.vc: the Vital Control
    │   ├── VcInputError (ValueError)
    │   └── DatalogCorruptError (ValueError)
    ├── AdfError                           onboard.adf: the autonomous driving function
    │   ├── InfeasibleLegError (ValueError)  a leg no profile within the limits can run in time
    │   └── NoJourneyError (RuntimeError)    AD asked for with no journey planned
    └── TrackDataError                     onboard.track_store: track data from the trackside
        ├── TrackDataCorruptError (ValueError)  a document or a stored copy fails its check
        └── TrackDataUnavailableError (LookupError)  no trackside gave the line in time

Foreign errors (casadi's, filterpy's, numpy's) are caught where they arise; a hazard or a
refusal in the running stack is an answer (an EB, an event, a refused command), not an
exception.
"""

from __future__ import annotations

__all__ = [
    "AdfError",
    "OnboardError",
    "TrackDataCorruptError",
    "TrackDataError",
    "TrackDataUnavailableError",
]


class OnboardError(Exception):
    """Base of every error raised by ``onboard``."""


class AdfError(OnboardError):
    """Base of the errors of :mod:`onboard.adf`."""


class TrackDataError(OnboardError):
    """Base of the errors of the onboard's track data (:mod:`onboard.track_store`)."""


class TrackDataCorruptError(TrackDataError, ValueError):
    """A line document, received or stored, whose SHA-256, id or content is not what it
    claims: it is never used."""


class TrackDataUnavailableError(TrackDataError, LookupError):
    """No trackside gave the line (not held, or no answer) before the wait ended."""
