"""``ato pki``: the deployment's own certificate authority for the Zenoh links.

Every Zenoh link of a deployment is TLS with mutual authentication (docs/security.md): each
router, trackside instance and vehicle holds a key and a certificate signed by the deployment's
CA, and the routers' access control keys its rules on the certificate's common name (the
vehicle's id, the trackside instance's, the router's name). A directory holds one CA::

    DIR/ca.pem  DIR/ca.key            the CA (the key stays on the machine that issues)
    DIR/NAME.pem  DIR/NAME.key        one party: its certificate and its key

Keys are ECDSA P-256, written owner-readable only. A party's certificate carries its role
(``trackside``, ``vehicle`` or ``router``) as the subject's organisational unit, serves as both
TLS client and server (a router connects to other routers and listens), and names the hosts it
may be reached as (``localhost`` and ``127.0.0.1`` unless given).
"""

from __future__ import annotations

import datetime as dt
import ipaddress
import os
import re
from collections.abc import Sequence
from dataclasses import dataclass
from enum import StrEnum
from pathlib import Path

from cryptography import x509
from cryptography.exceptions import InvalidSignature
from cryptography.hazmat.primitives import hashes, serialization
from cryptography.hazmat.primitives.asymmetric import ec
from cryptography.x509.oid import ExtendedKeyUsageOID, NameOID

from deploy._exceptions import DeployError

__all__ = [
    "CA_NAME",
    "DEFAULT_HOSTS",
    "Credentials",
    "PkiError",
    "Role",
    "credentials",
    "deployment_pki",
    "init_ca",
    "issue",
    "role_of",
]

CA_NAME = "ca"
"""The CA's files: ``ca.pem`` and ``ca.key``."""
CA_VALIDITY_DAYS = 3650
PARTY_VALIDITY_DAYS = 825
"""A party's certificate validity [days]: the longest public CAs issue, renewed by re-issuing."""
DEFAULT_HOSTS = ("localhost", "127.0.0.1")
_NAME = re.compile(r"[A-Za-z0-9][A-Za-z0-9_.-]{0,63}")


class PkiError(DeployError, ValueError):
    """A CA or certificate that cannot be made or used: which, and why."""


class Role(StrEnum):
    TRACKSIDE = "trackside"
    VEHICLE = "vehicle"
    ROUTER = "router"


@dataclass(frozen=True)
class Credentials:
    """The files a party's Zenoh sessions need: the CA to trust, its certificate and key."""

    ca: Path
    certificate: Path
    key: Path


def _write_private(path: Path, data: bytes) -> None:
    """Write ``data`` owner-readable only, replacing ``path`` at once (never half-written)."""
    partial = path.with_suffix(path.suffix + ".partial")
    descriptor = os.open(partial, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o600)
    with os.fdopen(descriptor, "wb") as file:
        file.write(data)
    partial.replace(path)


def _write_public(path: Path, data: bytes) -> None:
    partial = path.with_suffix(path.suffix + ".partial")
    partial.write_bytes(data)
    partial.replace(path)


def _key_pem(key: ec.EllipticCurvePrivateKey) -> bytes:
    return key.private_bytes(
        serialization.Encoding.PEM,
        serialization.PrivateFormat.PKCS8,
        serialization.NoEncryption(),
    )


def _check_name(name: str) -> None:
    if not _NAME.fullmatch(name) or name == CA_NAME:
        raise PkiError(f"bad name {name!r}: 1-64 letters, digits, '_', '.', '-', not {CA_NAME!r}")


def init_ca(directory: str | Path, *, name: str = "ato deployment CA") -> Path:
    """Make a CA in ``directory`` (created if need be): the path of its certificate.

    An existing CA is never overwritten: the certificates it signed would no longer verify.
    """
    directory = Path(directory)
    cert_path = directory / f"{CA_NAME}.pem"
    if cert_path.exists() or (directory / f"{CA_NAME}.key").exists():
        raise PkiError(f"{directory} already holds a CA; issue with it or choose another directory")
    directory.mkdir(parents=True, exist_ok=True)
    key = ec.generate_private_key(ec.SECP256R1())
    subject = x509.Name([x509.NameAttribute(NameOID.COMMON_NAME, name)])
    now = dt.datetime.now(dt.UTC)
    certificate = (
        x509.CertificateBuilder()
        .subject_name(subject)
        .issuer_name(subject)
        .public_key(key.public_key())
        .serial_number(x509.random_serial_number())
        .not_valid_before(now - dt.timedelta(minutes=5))
        .not_valid_after(now + dt.timedelta(days=CA_VALIDITY_DAYS))
        .add_extension(x509.BasicConstraints(ca=True, path_length=0), critical=True)
        .add_extension(
            x509.KeyUsage(
                digital_signature=False,
                content_commitment=False,
                key_encipherment=False,
                data_encipherment=False,
                key_agreement=False,
                key_cert_sign=True,
                crl_sign=True,
                encipher_only=False,
                decipher_only=False,
            ),
            critical=True,
        )
        .add_extension(x509.SubjectKeyIdentifier.from_public_key(key.public_key()), critical=False)
        .sign(key, hashes.SHA256())
    )
    _write_private(directory / f"{CA_NAME}.key", _key_pem(key))
    _write_public(cert_path, certificate.public_bytes(serialization.Encoding.PEM))
    return cert_path


def _load_ca(directory: Path) -> tuple[x509.Certificate, ec.EllipticCurvePrivateKey]:
    try:
        certificate = x509.load_pem_x509_certificate((directory / f"{CA_NAME}.pem").read_bytes())
        key = serialization.load_pem_private_key(
            (directory / f"{CA_NAME}.key").read_bytes(), password=None
        )
    except FileNotFoundError as exc:
        raise PkiError(f"no CA in {directory} (run `ato pki init {directory}`)") from exc
    except ValueError as exc:
        raise PkiError(f"the CA in {directory} is unreadable: {exc}") from exc
    if not isinstance(key, ec.EllipticCurvePrivateKey):
        raise PkiError(f"the CA key in {directory} is not an EC key")
    return certificate, key


def _alternative_names(hosts: Sequence[str]) -> x509.SubjectAlternativeName:
    names: list[x509.GeneralName] = []
    for host in hosts:
        try:
            names.append(x509.IPAddress(ipaddress.ip_address(host)))
        except ValueError:
            names.append(x509.DNSName(host))
    return x509.SubjectAlternativeName(names)


def issue(
    directory: str | Path,
    name: str,
    role: Role | str,
    *,
    hosts: Sequence[str] = DEFAULT_HOSTS,
) -> Credentials:
    """Issue ``name`` a key and a certificate for ``role``, signed by the CA in ``directory``.

    Issuing a name again replaces its key and certificate (a renewal, or a compromised key).
    """
    directory = Path(directory)
    _check_name(name)
    try:
        role = Role(role)
    except ValueError as exc:
        raise PkiError(f"bad role {role!r}: one of {', '.join(r.value for r in Role)}") from exc
    if not hosts:
        raise PkiError("a certificate needs at least one host name")
    ca_certificate, ca_key = _load_ca(directory)
    key = ec.generate_private_key(ec.SECP256R1())
    now = dt.datetime.now(dt.UTC)
    subject = x509.Name(
        [
            x509.NameAttribute(NameOID.COMMON_NAME, name),
            x509.NameAttribute(NameOID.ORGANIZATIONAL_UNIT_NAME, role.value),
        ]
    )
    certificate = (
        x509.CertificateBuilder()
        .subject_name(subject)
        .issuer_name(ca_certificate.subject)
        .public_key(key.public_key())
        .serial_number(x509.random_serial_number())
        .not_valid_before(now - dt.timedelta(minutes=5))
        .not_valid_after(now + dt.timedelta(days=PARTY_VALIDITY_DAYS))
        .add_extension(x509.BasicConstraints(ca=False, path_length=None), critical=True)
        .add_extension(
            x509.ExtendedKeyUsage(
                [ExtendedKeyUsageOID.SERVER_AUTH, ExtendedKeyUsageOID.CLIENT_AUTH]
            ),
            critical=False,
        )
        .add_extension(_alternative_names(hosts), critical=False)
        .add_extension(
            x509.AuthorityKeyIdentifier.from_issuer_public_key(ca_key.public_key()), critical=False
        )
        .sign(ca_key, hashes.SHA256())
    )
    found = credentials(directory, name, check=False)
    _write_private(found.key, _key_pem(key))
    _write_public(found.certificate, certificate.public_bytes(serialization.Encoding.PEM))
    return found


def credentials(directory: str | Path, name: str, *, check: bool = True) -> Credentials:
    """The files of ``name`` in ``directory``; with ``check``, that they exist and that the
    certificate is the CA's and valid now."""
    directory = Path(directory)
    found = Credentials(
        ca=directory / f"{CA_NAME}.pem",
        certificate=directory / f"{name}.pem",
        key=directory / f"{name}.key",
    )
    if check:
        for path in (found.ca, found.certificate, found.key):
            if not path.is_file():
                raise PkiError(f"{path} is missing (run `ato pki issue {directory} {name} ...`)")
        ca = x509.load_pem_x509_certificate(found.ca.read_bytes())
        certificate = x509.load_pem_x509_certificate(found.certificate.read_bytes())
        try:
            certificate.verify_directly_issued_by(ca)
        except (ValueError, TypeError, InvalidSignature) as exc:
            raise PkiError(f"{found.certificate} is not signed by {found.ca}") from exc
        now = dt.datetime.now(dt.UTC)
        if not certificate.not_valid_before_utc <= now <= certificate.not_valid_after_utc:
            raise PkiError(f"{found.certificate} is not valid now (re-issue it)")
    return found


def role_of(certificate_path: str | Path) -> tuple[str, Role]:
    """The common name and role a certificate was issued for."""
    certificate = x509.load_pem_x509_certificate(Path(certificate_path).read_bytes())
    common = certificate.subject.get_attributes_for_oid(NameOID.COMMON_NAME)
    unit = certificate.subject.get_attributes_for_oid(NameOID.ORGANIZATIONAL_UNIT_NAME)
    if not common or not unit:
        raise PkiError(f"{certificate_path} names no party or no role")
    try:
        return str(common[0].value), Role(str(unit[0].value))
    except ValueError as exc:
        raise PkiError(f"{certificate_path}: unknown role {unit[0].value!r}") from exc


def deployment_pki(
    directory: str | Path,
    *,
    vehicles: Sequence[str],
    tracksides: Sequence[str] = ("ts1",),
    routers: Sequence[str] = ("router",),
) -> Path:
    """A one-machine deployment's PKI in ``directory``: its CA, made on the first start, and a
    certificate for each router, trackside and vehicle that lacks one or whose certificate no
    longer verifies (``ato up``, ``ato demo``, the scenario runner). Its resolved path."""
    directory = Path(directory)
    if not (directory / f"{CA_NAME}.pem").exists():
        init_ca(directory)
    parties = [(name, Role.ROUTER) for name in routers]
    parties += [(name, Role.TRACKSIDE) for name in tracksides]
    parties += [(name, Role.VEHICLE) for name in vehicles]
    for name, role in parties:
        try:
            credentials(directory, name)
        except PkiError:
            issue(directory, name, role)
    return directory.resolve()
