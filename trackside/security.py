"""Password hashing (scrypt, memory-hard, from the standard library) and token digests.

A password hash is the string ``scrypt$N$r$p$salt$digest`` (salt and digest URL-safe base64):
it carries its own cost, so that a hash made at an older, cheaper cost still verifies, and
:func:`needs_rehash` tells the login to store a new one at the current cost (upgrade in place).

The cost is OWASP's Password Storage Cheat Sheet's minimum for scrypt, N = 2^17, r = 8, p = 1:
128 MiB and, on this project's 2-core reference machine, about 0.3-0.7 s of CPU per hash. So
that a burst of logins cannot take the service's memory, at most :data:`MAX_CONCURRENT_HASHES`
hashes run at once (the others wait their turn). The test suite alone lowers the cost for the
hashes it makes, through :func:`use_password_cost` (docs/security.md).
"""

from __future__ import annotations

import base64
import hashlib
import hmac
import secrets
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass

__all__ = [
    "LEGACY_COST",
    "MAX_CONCURRENT_HASHES",
    "OWASP_COST",
    "ScryptCost",
    "hash_password",
    "needs_rehash",
    "new_token",
    "password_cost",
    "token_digest",
    "use_password_cost",
    "verify_password",
]


@dataclass(frozen=True, slots=True)
class ScryptCost:
    """scrypt's work factors: ``n`` (CPU/memory cost, a power of two), ``r`` (block size) and
    ``p`` (parallelism)."""

    n: int
    r: int
    p: int

    @property
    def memory_bytes(self) -> int:
        """The memory one hash needs [bytes] (OpenSSL's count: 128 · r · (N + p + 2))."""
        return 128 * self.r * (self.n + self.p + 2)

    def acceptable(self) -> bool:
        """Whether a stored hash of this cost may be checked: sane factors, at most 256 MiB
        (a hash string is data: it must not be able to make a login take the machine)."""
        return (
            2 <= self.n <= 2**20
            and self.n & (self.n - 1) == 0
            and 1 <= self.r <= 32
            and 1 <= self.p <= 16
            and self.memory_bytes <= 256 * 1024 * 1024
        )


OWASP_COST = ScryptCost(n=2**17, r=8, p=1)
"""New hashes: OWASP's recommended minimum for scrypt (128 MiB per hash)."""
LEGACY_COST = ScryptCost(n=2**14, r=8, p=1)
"""The cost of the hashes stored before issue 20 (16 MiB): verified, then upgraded."""
MAX_CONCURRENT_HASHES = 4
"""Hashes computed at once, at most (4 · 128 MiB); more logins queue for a slot."""

_MAXMEM_SLACK_BYTES = 1024 * 1024
_slots = threading.BoundedSemaphore(MAX_CONCURRENT_HASHES)
_cost = OWASP_COST


def password_cost() -> ScryptCost:
    """The cost of the hashes :func:`hash_password` makes now."""
    return _cost


@contextmanager
def use_password_cost(cost: ScryptCost) -> Iterator[None]:
    """Make new hashes at ``cost`` within the block: for the test suite only, whose hundreds of
    logins would otherwise take minutes; a service always hashes at :data:`OWASP_COST`."""
    global _cost
    previous, _cost = _cost, cost
    try:
        yield
    finally:
        _cost = previous


def _scrypt(password: str, salt: bytes, cost: ScryptCost) -> bytes:
    with _slots:
        return hashlib.scrypt(
            password.encode(),
            salt=salt,
            n=cost.n,
            r=cost.r,
            p=cost.p,
            maxmem=cost.memory_bytes + _MAXMEM_SLACK_BYTES,
            dklen=32,
        )


def hash_password(password: str) -> str:
    """A new salted hash of ``password`` at the current cost, as ``scrypt$N$r$p$salt$digest``."""
    cost = _cost
    salt = secrets.token_bytes(16)
    digest = _scrypt(password, salt, cost)
    encode = base64.urlsafe_b64encode
    return f"scrypt${cost.n}${cost.r}${cost.p}${encode(salt).decode()}${encode(digest).decode()}"


def _parse(stored: str) -> tuple[ScryptCost, bytes, bytes]:
    """The cost, salt and digest of a stored hash; :class:`ValueError` when it is not one."""
    scheme, n, r, p, salt, digest = stored.split("$")
    cost = ScryptCost(n=int(n), r=int(r), p=int(p))
    if scheme != "scrypt" or not cost.acceptable():
        raise ValueError("not a scrypt hash of an acceptable cost")
    return cost, base64.urlsafe_b64decode(salt), base64.urlsafe_b64decode(digest)


def verify_password(password: str, stored: str) -> bool:
    """Whether ``password`` matches ``stored``, hashed at the cost ``stored`` names."""
    try:
        cost, salt, expected = _parse(stored)
        actual = _scrypt(password, salt, cost)
    except ValueError:
        return False
    return hmac.compare_digest(expected, actual)


def needs_rehash(stored: str) -> bool:
    """Whether ``stored`` was made at another cost than the current one (or is no hash of
    ours): after a successful login, store :func:`hash_password`'s instead."""
    try:
        cost, _, _ = _parse(stored)
    except ValueError:
        return True
    return cost != _cost


def new_token() -> str:
    """A new bearer token: 32 random bytes, URL-safe base64 (43 characters)."""
    return secrets.token_urlsafe(32)


def token_digest(token: str) -> str:
    """What is stored of a token: its SHA-256, so a leaked database holds no usable token."""
    return hashlib.sha256(token.encode()).hexdigest()
