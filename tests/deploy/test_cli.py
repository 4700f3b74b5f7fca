"""The ``ato`` command line (CONTRACT.md §1)."""

from __future__ import annotations

import subprocess

from typer.testing import CliRunner

from deploy.cli import app
from deploy.processes import ato_command

runner = CliRunner()


def test_subcommands_exist() -> None:
    result = runner.invoke(app, ["--help"])
    assert result.exit_code == 0
    for name in ("router", "trackside", "onboard", "demo", "bench"):
        assert name in result.output


def test_onboard_options() -> None:
    result = runner.invoke(app, ["onboard", "--help"])
    for option in ("--vehicle", "--zenoh", "--line", "--speed"):
        assert option in result.output


def test_onboard_refuses_a_non_positive_speed() -> None:
    result = runner.invoke(app, ["onboard", "--vehicle", "X", "--speed", "0"])
    assert result.exit_code != 0


def test_console_script_runs_as_module() -> None:
    completed = subprocess.run(
        ato_command("--help"), capture_output=True, text=True, timeout=60, check=False
    )
    assert completed.returncode == 0
    assert "trackside" in completed.stdout
