"""``ato sfa``'s line: a built-in line, or the onboard's verified copy of any line."""

from __future__ import annotations

from pathlib import Path

import pytest
import typer

from deploy.cli_sfa import _track_map
from onboard.track_store import TrackDataStore
from tests.deploy.valley_line import valley_line


def test_the_listener_reads_any_line_from_the_onboards_track_data(tmp_path: Path) -> None:
    line = valley_line()
    document = line.model_dump_json(round_trip=True)
    TrackDataStore(tmp_path).save(document, line_id=line.id, version=line.version())

    assert _track_map(line.id, tmp_path).version == line.version()
    assert _track_map("bologna-ring").line.id == "bologna-ring"


@pytest.mark.parametrize(
    ("content", "reason"),
    [(None, "no copy of line 'valley-test'"), ('{"id": "valley-test"}', "not a valid line")],
)
def test_a_missing_or_corrupted_copy_is_a_bad_parameter(
    tmp_path: Path, content: str | None, reason: str
) -> None:
    if content is not None:
        (tmp_path / "valley-test.json").write_text(content)
    with pytest.raises(typer.BadParameter, match=reason):
        _track_map("valley-test", tmp_path)
    with pytest.raises(typer.BadParameter, match="--track-dir"):
        _track_map("valley-test")
