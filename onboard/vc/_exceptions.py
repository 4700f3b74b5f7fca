"""The errors onboard.vc raises, in one place, re-exported by ``onboard.vc``.

::

    VcError (OnboardError)                  base of the package's errors
    ├── VcInputError (ValueError)        a bad call: a non-finite or negative duration, time
    │                                    going back, a message with the wrong number of
    │                                    sections or a sequence number out of range
    └── DatalogCorruptError (ValueError) a datalog line other than the last is not a record
                                         (defined in :mod:`onboard.vc.datalog`)

The tasks themselves never raise on valid inputs: a hazard is an answer (the EB flag, System
Decay), not an exception, so each cycle of Task A, B and C always yields its outputs.
"""

from __future__ import annotations

from onboard._exceptions import OnboardError

__all__ = ["VcError", "VcInputError"]


class VcError(OnboardError):
    """Base of the errors of :mod:`onboard.vc`."""


class VcInputError(VcError, ValueError):
    """A bad argument: non-finite, out of range, time going back."""
