"""The web edge: a request-body size limit before anything reads the body, and security headers.

A pure ASGI middleware, outermost in the application, so that it acts before routing,
authentication and body parsing:

- a request whose ``Content-Length`` exceeds ``max_body_bytes`` gets 413 at once, its body
  unread; one sent in chunks without a length gets 413 as soon as it has sent more (the
  application then stops reading it), so that no one, authenticated or not, makes the service
  buffer an unbounded body;
- every HTTP response carries ``X-Content-Type-Options: nosniff``, ``X-Frame-Options: DENY``,
  ``Referrer-Policy: no-referrer`` and ``Cross-Origin-Opener-Policy: same-origin``, and the
  API's answers ``Cache-Control: no-store`` (they carry tokens and live state);
- and a ``Content-Security-Policy`` (:func:`content_security_policy`): scripts, styles,
  images, fonts and connections (the API's WebSockets included) from the service's own origin
  only, no inline script, no plugins, no framing, forms posted only to itself; the only inline
  styles allowed are those the charting library inserts, by their hashes
  (:func:`inline_style_hashes`). The web console lives under it as it is
  (``tests/browser/test_csp.py``); FastAPI's own API documentation pages (``/docs``,
  ``/redoc``), which load Swagger UI and ReDoc from a CDN with an inline script, are the one
  exception.
"""

from __future__ import annotations

import base64
import hashlib
import json
import re
from collections.abc import Awaitable, Callable, MutableMapping
from typing import Any

from starlette.exceptions import HTTPException

__all__ = [
    "EMPTY_STYLE_HASH",
    "SECURITY_HEADERS",
    "EdgeMiddleware",
    "content_security_policy",
    "inline_style_hashes",
]

Scope = MutableMapping[str, Any]
Message = MutableMapping[str, Any]
Receive = Callable[[], Awaitable[Message]]
Send = Callable[[Message], Awaitable[None]]
App = Callable[[Scope, Receive, Send], Awaitable[None]]

SECURITY_HEADERS: tuple[tuple[bytes, bytes], ...] = (
    (b"x-content-type-options", b"nosniff"),
    (b"x-frame-options", b"DENY"),
    (b"referrer-policy", b"no-referrer"),
    (b"cross-origin-opener-policy", b"same-origin"),
)
EMPTY_STYLE_HASH = "'sha256-47DEQpj8HBSa+/TImW+5JCeuQeRkm5NMpJWZG3hSuFU='"
"""The CSP hash of an empty stylesheet: plotly creates an empty ``<style>`` and fills it
through the CSSOM (``insertRule``), which CSP does not restrict."""
_STYLE_TEXT = re.compile(r"""createElement\("style"\).{0,400}?\.textContent='([^'\\]*)'""", re.S)


def inline_style_hashes(script: str) -> tuple[str, ...]:
    """The CSP hash sources of the stylesheets ``script`` inserts as fixed text (a
    ``<style>`` whose ``textContent`` is a string literal without escapes: plotly's bundled
    map stylesheet), and of the empty one."""
    hashes = [EMPTY_STYLE_HASH]
    for match in _STYLE_TEXT.finditer(script):
        digest = base64.b64encode(hashlib.sha256(match.group(1).encode()).digest()).decode()
        hashes.append(f"'sha256-{digest}'")
    return tuple(dict.fromkeys(hashes))


def content_security_policy(style_hashes: tuple[str, ...] = ()) -> str:
    """The policy of every answer: the service's own origin only, no inline script; inline
    styles only those of ``style_hashes``. (``'self'`` covers the same origin's ``ws:`` and
    ``wss:`` in connect-src, CSP level 3.)"""
    styles = " ".join(("'self'", *style_hashes))
    return (
        f"default-src 'self'; script-src 'self'; style-src {styles}; img-src 'self' data:; "
        "font-src 'self'; connect-src 'self'; object-src 'none'; base-uri 'none'; "
        "frame-ancestors 'none'; form-action 'self'"
    )


_API_DOCUMENTATION = frozenset({"/docs", "/docs/oauth2-redirect", "/redoc"})


class EdgeMiddleware:
    """See the module's docstring."""

    def __init__(
        self,
        app: App,
        *,
        max_body_bytes: int,
        policy: str | None = None,
    ) -> None:
        self.app = app
        self.max_body_bytes = max_body_bytes
        policy = content_security_policy() if policy is None else policy
        self._csp_header = (b"content-security-policy", policy.encode())

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        declared = dict(scope.get("headers") or ()).get(b"content-length")
        if declared is not None and (not declared.isdigit() or int(declared) > self.max_body_bytes):
            await self._too_large(send)
            return
        path = str(scope.get("path", ""))
        no_store = path.startswith("/api/")
        policy = () if path in _API_DOCUMENTATION else (self._csp_header,)
        received = 0

        async def limited() -> Message:
            nonlocal received
            message = await receive()
            received += len(message.get("body", b""))
            if received > self.max_body_bytes:
                raise HTTPException(413, f"request body over {self.max_body_bytes} bytes")
            return message

        async def with_headers(message: Message) -> None:
            if message["type"] == "http.response.start":
                headers = list(message.get("headers") or [])
                headers += SECURITY_HEADERS
                headers += policy
                if no_store:
                    headers.append((b"cache-control", b"no-store"))
                message["headers"] = headers
            await send(message)

        await self.app(scope, limited, with_headers)

    async def _too_large(self, send: Send) -> None:
        body = json.dumps({"detail": f"request body over {self.max_body_bytes} bytes"}).encode()
        await send(
            {
                "type": "http.response.start",
                "status": 413,
                "headers": [
                    (b"content-type", b"application/json"),
                    (b"content-length", str(len(body)).encode()),
                    (b"connection", b"close"),
                    *SECURITY_HEADERS,
                    self._csp_header,
                ],
            }
        )
        await send({"type": "http.response.body", "body": body})
