"""The errors onboard.vc raises, in one place, re-exported by ``onboard.vc``.

::

    VcError (Exception)                  base of the package's errors
    ├── VcInputError (ValueError)        a bad call: a non-finite or negative duration, time
    │                                    going back, a message with the wrong number of
    │                                    sections or a sequence number out of range
    ├── ScenarioError (ValueError)       a scenario that cannot be run: a fault window that
    │                                    ends before it starts, an action after the run
    └── DatalogCorruptError (ValueError) a datalog line other than the last is not a record
                                         (defined in :mod:`onboard.vc.datalog`)

The tasks themselves never raise on valid inputs: a hazard is an answer (the EB flag, System
Decay), not an exception, so each cycle of Task A, B and C always yields its outputs.
"""

from __future__ import annotations

__all__ = ["ScenarioError", "VcError", "VcInputError"]


class VcError(Exception):
    """Base of the errors of :mod:`onboard.vc`."""


class VcInputError(VcError, ValueError):
    """A bad argument: non-finite, out of range, time going back."""


class ScenarioError(VcError, ValueError):
    """A scenario of the catalogue that does not make sense."""
