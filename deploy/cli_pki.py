"""``ato pki ...``: the deployment's certificate authority (docs/security.md).

- ``ato pki init DIR``: a CA in DIR (``ca.pem``, ``ca.key``); an existing one is kept.
- ``ato pki issue DIR NAME --role trackside|vehicle|router [--host H ...]``: NAME's key and
  certificate signed by DIR's CA; NAME is the vehicle's id, the trackside instance's or the
  router's, the common name the routers' access control keys its rules on.
- ``ato pki show FILE``: the name and role a certificate was issued for, and its validity.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

__all__ = ["pki_app"]

pki_app = typer.Typer(help="The deployment's CA for the Zenoh links.", no_args_is_help=True)


@pki_app.command("init")
def init(
    directory: Annotated[Path, typer.Argument(help="Where the CA's files go.")],
    name: Annotated[str, typer.Option(help="The CA's common name.")] = "ato deployment CA",
) -> None:
    """Make the deployment's CA (its key stays in DIR: keep DIR on the issuing machine)."""
    from deploy.pki import PkiError, init_ca

    try:
        path = init_ca(directory, name=name)
    except PkiError as exc:
        typer.echo(str(exc), err=True)
        raise typer.Exit(code=1) from exc
    typer.echo(f"CA written: {path} (key {path.with_suffix('.key')}, owner-readable only)")


@pki_app.command("issue")
def issue_command(
    directory: Annotated[Path, typer.Argument(help="The CA's directory.")],
    name: Annotated[str, typer.Argument(help="The party: a vehicle id, a trackside, a router.")],
    role: Annotated[str, typer.Option("--role", help="trackside, vehicle or router.")],
    host: Annotated[
        list[str] | None,
        typer.Option("--host", help="A host name or address it is reached as (repeatable)."),
    ] = None,
) -> None:
    """Issue NAME a key and a certificate signed by the CA in DIRECTORY."""
    from deploy.pki import DEFAULT_HOSTS, PkiError, issue

    try:
        found = issue(directory, name, role, hosts=tuple(host or DEFAULT_HOSTS))
    except PkiError as exc:
        typer.echo(str(exc), err=True)
        raise typer.Exit(code=1) from exc
    typer.echo(f"{role} {name}: {found.certificate} (key {found.key})")


@pki_app.command("show")
def show(certificate: Annotated[Path, typer.Argument(help="A certificate (PEM).")]) -> None:
    """The name and role a certificate was issued for."""
    from deploy.pki import PkiError, role_of

    try:
        name, role = role_of(certificate)
    except (PkiError, OSError, ValueError) as exc:
        typer.echo(f"{certificate}: {exc}", err=True)
        raise typer.Exit(code=1) from exc
    typer.echo(f"{name} ({role.value})")
