"""The results of a generated campaign's runs, kept on disk as each run ends, for ``--resume``.

A generated campaign of hundreds of whole-stack runs takes hours; stopped half-way (Ctrl-C, a
machine wanted for something else), it resumes where it was: ``ato campaign --generate N --seed
S --out DIR --resume`` runs only the scenarios of DIR without a kept result. A result is kept in
``DIR/results/<scenario>.json`` with what it is the result of: the SHA-256 of the scenario
file, the run's seed and the fingerprint of the code (:func:`code_fingerprint`). It is taken
again only when all three still match, so a campaign resumed after the code or the space
changed runs again what they change, and the summary is always the one tree's. Each file is
written to a temporary file and renamed: a run stopped while writing leaves no half result.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import os
import tempfile
from pathlib import Path

from pydantic import ValidationError

from deploy.scenario.campaign import Cell, CellResult
from deploy.scenario.kpi_model import Kpis

__all__ = ["CODE_PACKAGES", "RunStore", "code_fingerprint"]

CODE_PACKAGES = ("protocol", "trackdb", "onboard", "trackside", "deploy")
"""The packages whose sources make a run's result (the whole stack and its harness)."""


def code_fingerprint(root: Path | None = None) -> str:
    """SHA-256 over the names and contents of every Python source of :data:`CODE_PACKAGES`."""
    root = root or Path(__file__).resolve().parents[2]
    digest = hashlib.sha256()
    for package in CODE_PACKAGES:
        for path in sorted((root / package).rglob("*.py")):
            digest.update(path.relative_to(root).as_posix().encode() + b"\0")
            digest.update(path.read_bytes() + b"\0")
    return digest.hexdigest()


class RunStore:
    """One JSON file a run in ``directory``, matched to its scenario, seed and code.

    Parameters
    ----------
    directory : Path
        Where the results are kept (made on the first save).
    code : str
        The fingerprint of the code the runs are made with (:func:`code_fingerprint`).
    """

    def __init__(self, directory: Path, code: str) -> None:
        self.directory = directory
        self.code = code

    def _path(self, cell: Cell) -> Path:
        return self.directory / f"{Path(cell.scenario).stem}.json"

    def _key(self, cell: Cell) -> dict[str, object]:
        scenario = hashlib.sha256(Path(cell.scenario).read_bytes()).hexdigest()
        return {"scenario_sha256": scenario, "seed": cell.seed, "code": self.code}

    def save(self, result: CellResult) -> None:
        """Keep ``result`` (atomically: the old file or the new one, never half of one)."""
        kpis = None if result.kpis is None else result.kpis.model_dump(mode="json")
        record = self._key(result.cell) | {"kpis": kpis, "error": result.error}
        self.directory.mkdir(parents=True, exist_ok=True)
        handle, temporary = tempfile.mkstemp(suffix=".tmp", dir=self.directory)
        try:
            with os.fdopen(handle, "w", encoding="utf-8") as out:
                json.dump(record, out)
            os.replace(temporary, self._path(result.cell))
        except BaseException:
            with contextlib.suppress(OSError):
                os.unlink(temporary)
            raise

    def load(self, cell: Cell) -> CellResult | None:
        """The kept result of ``cell`` if it was made of this scenario file, seed and code;
        None otherwise (none kept, another scenario, seed or code, an unreadable file)."""
        try:
            record = json.loads(self._path(cell).read_text(encoding="utf-8"))
            if not isinstance(record, dict) or any(
                record.get(key) != value for key, value in self._key(cell).items()
            ):
                return None
            kpis = None if record["kpis"] is None else Kpis.model_validate(record["kpis"])
            error = record["error"]
        except (OSError, ValueError, KeyError, ValidationError):
            return None
        if kpis is None and not isinstance(error, str):
            return None
        return CellResult(cell, kpis, error if isinstance(error, str) else None)
