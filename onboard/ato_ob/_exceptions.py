"""The errors onboard.ato_ob raises, in one place, re-exported by ``onboard.ato_ob``.

::

    AtoObError (OnboardError)                  base of the package's errors
    ├── AtoObInputError (ValueError)        a bad call: a non-finite or negative value, time
    │                                       going back, an ETCS-OB output received in the future
    └── RequestRefusedError                 an operator request the state forbids now: engage
                                            outside RE, disengage with nothing engaged, reset
                                            outside FA or while the fault's cause remains

A refusal is an answer, not a failure: the interface manager turns it into the command's reply
to the console. :meth:`onboard.ato_ob.AtoObController.step` never raises on valid inputs.
"""

from __future__ import annotations

from onboard._exceptions import OnboardError

__all__ = ["AtoObError", "AtoObInputError", "RequestRefusedError"]


class AtoObError(OnboardError):
    """Base of the errors of :mod:`onboard.ato_ob`."""


class AtoObInputError(AtoObError, ValueError):
    """A bad argument: non-finite, out of range, time going back."""


class RequestRefusedError(AtoObError):
    """An operator request (engage, disengage, reset) that the current state does not allow."""
