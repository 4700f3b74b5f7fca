"""The errors onboard.etcs raises, in one place, re-exported by ``onboard.etcs``.

::

    EtcsError (OnboardError)                      base of the package's errors
    ├── EtcsInputError (ValueError)            a bad call: a non-finite or negative value, time
    │                                          going back, a limit the target does not have
    ├── TrainDataError (ValueError)            fixed values, national values, train data or
    │                                          odometry accuracy out of range
    ├── MovementAuthorityError (ValueError)    an MA whose distances or timers do not make sense
    ├── BrakingCapabilityError (ValueError)    a safe or expected deceleration ≤ 0 on the way
    │                                          to a target (a downhill the brakes cannot hold)
    └── TransitionRefusedError                 a request the mode forbids now: a trip
                                               acknowledged while moving, insertion while not
                                               isolated, start of mission outside SB and PT

Errors are raised by the library calls only; the supervision itself never raises on a valid
input, so a cycle of :meth:`onboard.etcs.EtcsOnboard.step` always yields its commands.
"""

from __future__ import annotations

from onboard._exceptions import OnboardError

__all__ = [
    "BrakingCapabilityError",
    "EtcsError",
    "EtcsInputError",
    "MovementAuthorityError",
    "TrainDataError",
    "TransitionRefusedError",
]


class EtcsError(OnboardError):
    """Base of the errors of :mod:`onboard.etcs`."""


class EtcsInputError(EtcsError, ValueError):
    """A bad argument: non-finite, out of range, time going back, or a limit a target lacks."""


class TrainDataError(EtcsError, ValueError):
    """Fixed values, national values, train data or odometry accuracy out of range."""


class MovementAuthorityError(EtcsError, ValueError):
    """A movement authority whose distances, sections or timers do not make sense."""


class BrakingCapabilityError(EtcsError, ValueError):
    """A deceleration ≤ 0 [m/s²] on the way to a target: the train could not stop there."""


class TransitionRefusedError(EtcsError):
    """A driver, ATO or VC request that the current mode or motion does not allow."""
