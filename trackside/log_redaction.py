"""Bearer tokens never reach a log: a filter that blanks them out of every record.

Nothing of ours logs a token, and the console sends its WebSocket token in a message, not in the
URL (``trackside.api.routes.ws``); but uvicorn logs each request's path with its query string,
and anyone can put ``?token=...`` (or ``access_token=``) in a URL or a token in an
exception's text. :class:`TokenRedactingFilter` rewrites such a record's message, arguments
and traceback before any handler formats it. :func:`install_token_redaction` puts it on the
loggers that see requests (uvicorn's) and on the handlers of the root and uvicorn loggers
(which also see what propagates from every other logger). It runs at the service's start-up,
after uvicorn has configured its logging.
"""

from __future__ import annotations

import logging
import re
from collections.abc import Iterable

__all__ = [
    "REDACTED",
    "REQUEST_LOGGERS",
    "TokenRedactingFilter",
    "install_token_redaction",
    "redact_tokens",
]

REDACTED = "[redacted]"
REQUEST_LOGGERS = ("uvicorn", "uvicorn.access", "uvicorn.error")
"""uvicorn's loggers: the access log (path and query string of each request, WebSocket
handshakes included) and the server's own messages."""

_PATTERNS = (
    # Authorization: Bearer <token>
    re.compile(r"(?i)(\bbearer\s+)[A-Za-z0-9._~+/=-]+"),
    # token=..., access_token=... in a query string or a form
    re.compile(r"(?i)(\b(?:access_)?token=)[^&\s\"'#]+"),
    # "token": "...", "access_token": "..." in JSON or a Python repr
    re.compile(r"""(?i)(["']?(?:access_)?token["']?\s*:\s*["'])[^"']+"""),
)


def redact_tokens(text: str) -> str:
    """``text`` with each bearer token in it replaced by :data:`REDACTED`."""
    for pattern in _PATTERNS:
        text = pattern.sub(lambda match: match.group(1) + REDACTED, text)
    return text


def _redact_argument(argument: object) -> object:
    """A log argument, redacted when its text carries a token; numbers and other arguments
    without one are kept as they are (``%d`` formats still work)."""
    if argument is None or isinstance(argument, int | float):
        return argument
    text = argument if isinstance(argument, str) else str(argument)
    redacted = redact_tokens(text)
    return argument if redacted == text else redacted


class TokenRedactingFilter(logging.Filter):
    """Rewrites a record so that no bearer token is left in it; lets every record through."""

    def filter(self, record: logging.LogRecord) -> bool:
        # Argument by argument first, which keeps the record's shape (uvicorn's access
        # formatter unpacks its arguments); then the whole message, for a token that the
        # format string and an argument share.
        if isinstance(record.args, tuple):
            record.args = tuple(_redact_argument(argument) for argument in record.args)
        elif isinstance(record.args, dict):
            record.args = {key: _redact_argument(value) for key, value in record.args.items()}
        try:
            message = record.getMessage()
        except (TypeError, ValueError):  # a malformed call: left for logging to report
            message = None
        if message is not None and redact_tokens(message) != message:
            record.msg, record.args = redact_tokens(message), ()
        if record.exc_info and not record.exc_text:
            record.exc_text = logging.Formatter().formatException(record.exc_info)
        if record.exc_text:
            record.exc_text = redact_tokens(record.exc_text)
        return True


def _add_once(holder: logging.Logger | logging.Handler) -> None:
    if not any(isinstance(existing, TokenRedactingFilter) for existing in holder.filters):
        holder.addFilter(TokenRedactingFilter())


def install_token_redaction(logger_names: Iterable[str] = REQUEST_LOGGERS) -> None:
    """Put a :class:`TokenRedactingFilter` on those loggers and on the handlers of them and of
    the root logger (once each: installing again adds nothing)."""
    loggers = [logging.getLogger(name) for name in logger_names]
    for logger in loggers:
        _add_once(logger)
    for logger in [logging.getLogger(), *loggers]:
        for handler in logger.handlers:
            _add_once(handler)
