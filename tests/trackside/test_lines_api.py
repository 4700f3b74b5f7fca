"""The lines REST API on SQLite and PostgreSQL: reads, import, export, versions, profiles."""

from __future__ import annotations

import hashlib
from typing import Any

import pytest
from alembic.autogenerate import compare_metadata
from alembic.migration import MigrationContext
from fastapi.testclient import TestClient

from tests.trackdb.layouts import small_ring, tiny_line, without_geodetic
from tests.trackside.conftest import MakeClient, login
from trackdb import SEED_LINES, TrackMap, load_seed_line
from trackdb.storage import metadata as track_data_metadata
from trackside.db import create_database_engine, migrate
from trackside.services.lines import MAX_PROFILE_POINTS

Headers = dict[str, str]
RING = "bologna-ring"
KMH = 1.0 / 3.6


def _user(client: TestClient, admin_headers: Headers, role: str) -> Headers:
    body = {"username": f"{role}-user", "password": f"{role}-password", "role": role}
    assert client.post("/api/v1/users", headers=admin_headers, json=body).status_code == 201
    return login(client, body["username"], body["password"])


@pytest.fixture
def observer(client: TestClient, admin_headers: Headers) -> Headers:
    return _user(client, admin_headers, "observer")


def _import(client: TestClient, headers: Headers, document: Any) -> Any:
    return client.post("/api/v1/lines", headers=headers, json=document)


@pytest.mark.parametrize(
    "path",
    [
        "/api/v1/lines",
        f"/api/v1/lines/{RING}",
        f"/api/v1/lines/{RING}/export",
        f"/api/v1/lines/{RING}/version",
        f"/api/v1/lines/{RING}/versions",
        f"/api/v1/lines/{RING}/profile",
    ],
)
def test_reads_need_a_token(client: TestClient, path: str) -> None:
    assert client.get(path).status_code == 401
    assert client.get(path, headers={"Authorization": "Bearer nonsense"}).status_code == 401


def test_seed_lines_are_listed(client: TestClient, observer: Headers) -> None:
    response = client.get("/api/v1/lines", headers=observer)
    assert response.status_code == 200
    listed = {item["id"]: item for item in response.json()}
    assert set(listed) == set(SEED_LINES)
    ring = load_seed_line(RING)
    assert listed[RING] == {
        "id": RING,
        "name": ring.name,
        "version": ring.version(),
        "length_m": ring.length_m,
        "ring": True,
        "etcs_level": 1,
    }
    assert listed["milano-bologna"]["etcs_level"] == 2


def test_no_seed_lines_when_disabled(make_client: MakeClient) -> None:
    client = make_client(seed_lines=False)
    headers = login(client, "root", "admin-password")
    assert client.get("/api/v1/lines", headers=headers).json() == []


def test_document_version_and_export(client: TestClient, observer: Headers) -> None:
    ring = load_seed_line(RING)
    document = client.get(f"/api/v1/lines/{RING}", headers=observer)
    assert document.status_code == 200
    assert document.json() == ring.model_dump(mode="json")
    assert document.headers["etag"] == f'"{ring.version()}"'
    version = client.get(f"/api/v1/lines/{RING}/version", headers=observer).json()
    assert version == {"id": RING, "version": ring.version()}
    exported = client.get(f"/api/v1/lines/{RING}/export", headers=observer)
    assert exported.status_code == 200
    assert exported.headers["content-type"] == "application/json"
    assert exported.headers["content-disposition"].startswith("attachment; filename=")
    assert hashlib.sha256(exported.content).hexdigest() == ring.version()
    [stored] = client.get(f"/api/v1/lines/{RING}/versions", headers=observer).json()
    assert stored["version"] == ring.version()
    assert stored["current"] is True


def test_import_needs_the_admin_role(client: TestClient, admin_headers: Headers) -> None:
    document = tiny_line().model_dump(mode="json")
    assert _import(client, {}, document).status_code == 401
    for role in ("observer", "driver"):
        assert _import(client, _user(client, admin_headers, role), document).status_code == 403
    assert client.get("/api/v1/lines/tiny", headers=admin_headers).status_code == 404


def test_import_versions_and_reimport(client: TestClient, admin_headers: Headers) -> None:
    first, second = tiny_line(), tiny_line(name="Tiny, TSR lifted", tsr_speed_kmh=60.0)
    created = _import(client, admin_headers, first.model_dump(mode="json"))
    assert created.status_code == 201
    assert created.json()["version"] == first.version()
    assert _import(client, admin_headers, second.model_dump(mode="json")).status_code == 201
    # The same document again: stored already, made current, nothing new.
    again = _import(client, admin_headers, first.model_dump(mode="json"))
    assert again.status_code == 200
    assert again.json()["version"] == first.version()
    versions = client.get("/api/v1/lines/tiny/versions", headers=admin_headers).json()
    assert [(v["version"], v["current"]) for v in versions] == [
        (first.version(), True),
        (second.version(), False),
    ]
    old = client.get(f"/api/v1/lines/tiny?version={second.version()}", headers=admin_headers)
    assert old.json()["name"] == "Tiny, TSR lifted"
    exported = client.get(
        f"/api/v1/lines/tiny/export?version={second.version()}", headers=admin_headers
    )
    assert hashlib.sha256(exported.content).hexdigest() == second.version()
    listed = [line["id"] for line in client.get("/api/v1/lines", headers=admin_headers).json()]
    assert listed == sorted([*SEED_LINES, "tiny"])


def test_the_exported_document_imports_to_the_same_version(
    client: TestClient, admin_headers: Headers
) -> None:
    exported = client.get(f"/api/v1/lines/{RING}/export", headers=admin_headers)
    response = client.post(
        "/api/v1/lines",
        headers=admin_headers | {"Content-Type": "application/json"},
        content=exported.content,
    )
    assert response.status_code == 200
    assert response.json()["version"] == load_seed_line(RING).version()


def test_an_invalid_line_is_422_with_every_problem(
    client: TestClient, admin_headers: Headers
) -> None:
    document = tiny_line().model_dump(mode="json")
    document["speed_limit_mps"][0]["value"] = 0.0
    document["stopping_points"][0]["position_m"] = 2000.0
    response = _import(client, admin_headers, document)
    assert response.status_code == 422
    detail = response.json()["detail"]
    assert "tiny" in detail["message"]
    assert any("non-positive speed" in problem for problem in detail["problems"])
    assert any("stopping_points[0]" in problem for problem in detail["problems"])
    assert client.get("/api/v1/lines/tiny", headers=admin_headers).status_code == 404


@pytest.mark.parametrize("body", [b"{not json", b"[1, 2]", b'"a line"', b""])
def test_a_body_that_is_no_line_is_422(
    client: TestClient, admin_headers: Headers, body: bytes
) -> None:
    response = client.post("/api/v1/lines", headers=admin_headers, content=body)
    assert response.status_code == 422
    assert response.json()["detail"]["problems"]


@pytest.mark.parametrize("suffix", ["", "/export", "/version", "/versions", "/profile"])
def test_unknown_line_is_404(client: TestClient, observer: Headers, suffix: str) -> None:
    assert client.get(f"/api/v1/lines/nowhere{suffix}", headers=observer).status_code == 404


@pytest.mark.parametrize("suffix", ["", "/export", "/profile"])
def test_unknown_version_is_404(client: TestClient, observer: Headers, suffix: str) -> None:
    path = f"/api/v1/lines/{RING}{suffix}?version={'0' * 64}"
    response = client.get(path, headers=observer)
    assert response.status_code == 404
    assert "no version" in response.json()["detail"]


@pytest.mark.parametrize("line_id", sorted(SEED_LINES))
def test_profile_of_a_whole_seed_line(client: TestClient, observer: Headers, line_id: str) -> None:
    line = load_seed_line(line_id)
    track = TrackMap(line)
    response = client.get(f"/api/v1/lines/{line_id}/profile", headers=observer)
    assert response.status_code == 200
    profile = response.json()
    chainages = profile["chainage_m"]
    assert profile["version"] == line.version()
    assert profile["ring"] == line.ring
    assert len(chainages) == 1001
    assert chainages[0] == 0.0
    assert chainages[-1] == line.length_m
    for key in ("gradient_permille", "curvature_per_m", "speed_limit_mps", "mrsp_mps"):
        assert len(profile[key]) == len(chainages), key
    assert len(profile["altitude_m"]) == len(chainages)
    for index in range(0, len(chainages), 97):
        chainage = chainages[index]
        assert profile["speed_limit_mps"][index] == track.speed_limit_mps(chainage)
        assert profile["gradient_permille"][index] == track.gradient_permille(chainage)
        assert profile["curvature_per_m"][index] == track.curvature_per_m(chainage)
        assert profile["altitude_m"][index] == pytest.approx(track.altitude_m(chainage), abs=1e-9)
    assert all(m <= s for m, s in zip(profile["mrsp_mps"], profile["speed_limit_mps"], strict=True))


def test_profile_wraps_on_a_ring(client: TestClient, observer: Headers) -> None:
    line = load_seed_line(RING)
    start_m = line.length_m - 100.0
    query = f"from={start_m}&to={line.length_m + 200.0}&step=50"
    profile = client.get(f"/api/v1/lines/{RING}/profile?{query}", headers=observer).json()
    assert profile["chainage_m"] == [start_m + 50.0 * index for index in range(7)]
    track = TrackMap(line)
    # Past the length, the values are those from the origin on.
    assert profile["speed_limit_mps"][2:] == [
        track.speed_limit_mps(c) for c in (0, 50, 100, 150, 200)
    ]
    assert profile["curvature_per_m"][0] == pytest.approx(1 / 400.0)
    assert profile["curvature_per_m"][3] == 0.0
    first_lap = client.get(f"/api/v1/lines/{RING}/profile?from=0&to=200&step=50", headers=observer)
    assert profile["altitude_m"][2:] == pytest.approx(first_lap.json()["altitude_m"], abs=1e-6)


def test_profile_shows_a_tsr_in_the_mrsp_and_null_altitude_without_geodesy(
    client: TestClient, admin_headers: Headers
) -> None:
    line = without_geodetic(tiny_line())
    assert _import(client, admin_headers, line.model_dump(mode="json")).status_code == 201
    response = client.get(
        "/api/v1/lines/tiny/profile?from=300&to=500&step=100", headers=admin_headers
    )
    profile = response.json()
    assert profile["chainage_m"] == [300.0, 400.0, 500.0]
    assert profile["speed_limit_mps"] == pytest.approx([72 * KMH, 54 * KMH, 54 * KMH])
    assert profile["mrsp_mps"] == pytest.approx([72 * KMH, 30 * KMH, 54 * KMH])
    assert profile["gradient_permille"] == [5.0, 0.0, 0.0]
    assert profile["altitude_m"] is None


def test_profile_ends_at_to_when_the_step_does_not_divide(
    client: TestClient, admin_headers: Headers
) -> None:
    assert _import(client, admin_headers, small_ring().model_dump(mode="json")).status_code == 201
    path = "/api/v1/lines/small-ring/profile?from=10&to=1000&step=300"
    assert client.get(path, headers=admin_headers).json()["chainage_m"] == [
        10.0,
        310.0,
        610.0,
        910.0,
        1000.0,
    ]


@pytest.mark.parametrize(
    ("line_id", "query", "fragment"),
    [
        ("milano-bologna", "to=200001", "beyond the end"),
        ("milano-bologna", "from=-1", "at least 0"),
        ("milano-bologna", "from=500&to=400", "after from"),
        ("milano-bologna", "from=500&to=500", "after from"),
        ("milano-bologna", "step=0", "positive"),
        ("milano-bologna", "step=-5", "positive"),
        ("milano-bologna", "step=1", f"more than {MAX_PROFILE_POINTS}"),
        (RING, "from=0&to=1e9&step=1", f"more than {MAX_PROFILE_POINTS}"),
        (RING, "step=1e-300", f"more than {MAX_PROFILE_POINTS}"),
        (RING, "to=inf", "finite"),
    ],
)
def test_bad_profile_ranges_are_422(
    client: TestClient, observer: Headers, line_id: str, query: str, fragment: str
) -> None:
    response = client.get(f"/api/v1/lines/{line_id}/profile?{query}", headers=observer)
    assert response.status_code == 422, response.text
    detail = response.json()["detail"]
    assert fragment in detail["message"]
    assert detail["problems"]


def test_the_largest_profile_is_allowed(client: TestClient, observer: Headers) -> None:
    response = client.get("/api/v1/lines/milano-bologna/profile?step=10", headers=observer)
    assert response.status_code == 200
    assert len(response.json()["chainage_m"]) == MAX_PROFILE_POINTS


def test_a_restart_keeps_the_imported_version_of_a_seed_line(make_client: MakeClient) -> None:
    client = make_client()
    headers = login(client, "root", "admin-password")
    document = load_seed_line(RING).model_dump(mode="json") | {"name": "Ring, surveyed"}
    imported = _import(client, headers, document).json()["version"]
    restarted = make_client()
    headers = login(restarted, "root", "admin-password")
    version = restarted.get(f"/api/v1/lines/{RING}/version", headers=headers).json()["version"]
    assert version == imported


def test_openapi_describes_the_line_routes(client: TestClient) -> None:
    paths = client.get("/openapi.json").json()["paths"]
    for path in (
        "",
        "/{line_id}",
        "/{line_id}/export",
        "/{line_id}/version",
        "/{line_id}/versions",
        "/{line_id}/profile",
    ):
        operations = paths[f"/api/v1/lines{path}"]
        for operation in operations.values():
            assert operation["description"]
            assert "\n" not in operation["description"]
    body = paths["/api/v1/lines"]["post"]["requestBody"]["content"]["application/json"]
    assert body["schema"] == {"$ref": "#/components/schemas/Line"}


def test_migrations_create_the_line_tables_as_trackdb_declares_them(database_url: str) -> None:
    ours = set(track_data_metadata.tables)

    def only_ours(name: str | None, type_: str, _parents: object) -> bool:
        return type_ != "table" or name in ours

    engine = create_database_engine(database_url)
    try:
        migrate(engine)
        with engine.connect() as connection:
            context = MigrationContext.configure(connection, opts={"include_name": only_ours})
            differences = compare_metadata(context, track_data_metadata)
    finally:
        engine.dispose()
    assert differences == []
