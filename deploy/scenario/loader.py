"""Reading scenario files: TOML in, a :class:`ScenarioSpec` out, or an error with its line.

A malformed file is rejected with the file, the line and the reason
(:class:`ScenarioFileError`): a TOML syntax error where the parser stopped, a validation error
on the line of the offending key (or of its table when the key is missing).
"""

from __future__ import annotations

import re
import tomllib
from collections.abc import Sequence
from pathlib import Path

from pydantic import ValidationError

from deploy._exceptions import DeployError
from deploy.scenario.schema import ScenarioSpec

__all__ = [
    "SCENARIO_DIR",
    "ScenarioFileError",
    "load_scenario",
    "parse_scenario",
    "scenario_names",
]

SCENARIO_DIR = Path(__file__).resolve().parent.parent / "scenarios"
"""The scenario library shipped with ato."""

_TABLE = re.compile(r"^\s*(\[\[?)\s*([A-Za-z0-9_.\"-]+)\s*\]\]?\s*(#.*)?$")
_KEY = re.compile(r"^\s*([A-Za-z0-9_-]+)\s*=")
_TOML_POSITION = re.compile(r"\(at line (\d+), column \d+\)")


class ScenarioFileError(DeployError, ValueError):
    """A scenario file that cannot be used: where, and why."""

    def __init__(self, path: str, line: int | None, reason: str) -> None:
        self.path = path
        self.line = line
        self.reason = reason
        where = path if line is None else f"{path}:{line}"
        super().__init__(f"{where}: {reason}")


def _key_lines(
    text: str,
) -> tuple[list[tuple[int, tuple[object, ...], str]], dict[tuple[object, ...], int]]:
    """Each ``key = value`` line with its table path, and each table header's line."""
    keys: list[tuple[int, tuple[object, ...], str]] = []
    headers: dict[tuple[object, ...], int] = {}
    counts: dict[tuple[str, ...], int] = {}
    path: tuple[object, ...] = ()
    for number, line in enumerate(text.splitlines(), start=1):
        table = _TABLE.match(line)
        if table is not None:
            names = tuple(part.strip('"') for part in table.group(2).split("."))
            if table.group(1) == "[[":
                index = counts.get(names, 0)
                counts[names] = index + 1
                path = (*names, index)
            else:
                path = names
            headers[path] = number
            continue
        key = _KEY.match(line)
        if key is not None:
            keys.append((number, path, key.group(1)))
    return keys, headers


def _line_of(text: str, location: Sequence[object]) -> int | None:
    keys, headers = _key_lines(text)
    # A tagged union puts the tag in the location (faults.0.ato_failure.end_s): not a key.
    names = {name for _, _, name in keys} | {p for path in headers for p in path}
    loc = tuple(part for part in location if not isinstance(part, str) or part in names)
    for split in range(len(loc) - 1, -1, -1):
        table, key = loc[:split], loc[split]
        for number, path, name in keys:
            if path == table and name == key:
                return number
    for split in range(len(loc), 0, -1):
        if loc[:split] in headers:
            return headers[loc[:split]]
    return None


def parse_scenario(
    text: str, *, path: str = "<scenario>", base_dir: Path | None = None
) -> ScenarioSpec:
    """Parse and validate a scenario's TOML text; a relative ``line_file`` is made relative to
    ``base_dir`` (the scenario file's directory) when one is given."""
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        position = _TOML_POSITION.search(str(exc))
        reason = _TOML_POSITION.sub("", str(exc)).strip()
        raise ScenarioFileError(
            path, int(position.group(1)) if position else None, f"TOML: {reason}"
        ) from exc
    try:
        spec = ScenarioSpec.model_validate(data)
    except ValidationError as exc:
        error = exc.errors()[0]
        location = tuple(error["loc"])
        if error["type"] == "union_tag_invalid":
            location += ("kind",)
        where = ".".join(str(part) for part in location) or "the file"
        message = error["msg"].removeprefix("Value error, ")
        raise ScenarioFileError(path, _line_of(text, location), f"{where}: {message}") from exc
    if spec.line_file is not None and base_dir is not None:
        line_file = base_dir / spec.line_file
        spec = spec.model_copy(update={"line_file": str(line_file)})
    return spec


def load_scenario(name_or_path: str | Path) -> ScenarioSpec:
    """A scenario of the library by name, or a TOML file by path."""
    path = Path(name_or_path)
    if not path.is_file():
        path = SCENARIO_DIR / f"{name_or_path}.toml"
        if not path.is_file():
            known = ", ".join(scenario_names())
            raise ScenarioFileError(
                str(name_or_path), None, f"no such scenario file or name (known: {known})"
            )
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise ScenarioFileError(str(path), None, f"cannot read it: {exc}") from exc
    return parse_scenario(text, path=str(path), base_dir=path.parent)


def scenario_names() -> list[str]:
    """The names of the library's scenarios, sorted."""
    return sorted(path.stem for path in SCENARIO_DIR.glob("*.toml"))
