"""The ATO-TS application: ``create_app(settings)`` and the ``main()`` that serves it."""

from __future__ import annotations

import logging
from collections.abc import AsyncIterator
from contextlib import AbstractContextManager, asynccontextmanager, nullcontext

import zenoh
from fastapi import APIRouter, FastAPI
from fastapi.responses import FileResponse
from fastapi.staticfiles import StaticFiles
from sqlalchemy.orm import Session, sessionmaker

from protocol import open_session
from trackdb import LineNotFoundError
from trackdb.storage import current_version
from trackside.api.routes import auth, journeys, lines, vehicles, ws
from trackside.api.routes import users as users_routes
from trackside.bridge import ZenohBridge
from trackside.config import Settings
from trackside.db import create_database_engine, migrate
from trackside.models import Role
from trackside.services import lines as lines_service
from trackside.services import users

__all__ = ["create_app", "main"]

_log = logging.getLogger(__name__)


def _bootstrap_admin(settings: Settings, factory: sessionmaker[Session]) -> None:
    if settings.admin_user and settings.admin_password:
        with factory() as db, db.begin():
            users.ensure_user(
                db, settings.admin_user, settings.admin_password.get_secret_value(), Role.ADMIN
            )


def _line_version(factory: sessionmaker[Session], line_id: str) -> str | None:
    """The current version of a stored line, for onboard track-data checks."""
    with factory() as db:
        try:
            return current_version(db, line_id)
        except LineNotFoundError:
            return None


def _seed_lines(settings: Settings, factory: sessionmaker[Session]) -> None:
    if settings.seed_lines:
        with factory() as db, db.begin():
            imported = lines_service.ensure_seed_lines(db)
        if imported:
            _log.info("imported seed lines: %s", ", ".join(imported))


def create_app(settings: Settings, *, zenoh_session: zenoh.Session | None = None) -> FastAPI:
    """Build the service. Without ``zenoh_session`` it opens (and closes) its own."""

    @asynccontextmanager
    async def lifespan(app: FastAPI) -> AsyncIterator[None]:
        engine = create_database_engine(settings.database_url)
        migrate(engine)
        factory = sessionmaker(engine, expire_on_commit=False)
        _bootstrap_admin(settings, factory)
        _seed_lines(settings, factory)
        app.state.settings = settings
        app.state.session_factory = factory
        sessions: AbstractContextManager[zenoh.Session] = (
            nullcontext(zenoh_session)
            if zenoh_session is not None
            else open_session(settings.zenoh())
        )
        with sessions as session:
            bridge = ZenohBridge(
                session,
                instance_id=settings.instance_id,
                line_version=lambda line_id: _line_version(factory, line_id),
            )
            app.state.bridge = bridge
            try:
                yield
            finally:
                bridge.close()
                engine.dispose()

    app = FastAPI(
        title="ATO-TS",
        summary="Trackside service of the ato GoA4 ATO over ETCS stack",
        version="0.1.0",
        lifespan=lifespan,
    )
    api = APIRouter(prefix="/api/v1")
    api.include_router(auth.router)
    api.include_router(users_routes.router)
    api.include_router(vehicles.router)
    api.include_router(lines.router)
    api.include_router(journeys.router)
    api.include_router(ws.router)
    app.include_router(api)

    @app.get("/healthz", tags=["health"])
    def health() -> dict[str, str]:
        """Liveness of the service itself (no authentication)."""
        return {"status": "ok"}

    webui = settings.webui_dir
    if webui.is_dir():
        app.mount("/static", StaticFiles(directory=webui), name="static")

        @app.get("/", include_in_schema=False)
        def index() -> FileResponse:
            return FileResponse(webui / "index.html")

    return app


def main(settings: Settings | None = None, *, host: str = "127.0.0.1", port: int = 8000) -> None:
    """Serve ATO-TS with uvicorn until interrupted."""
    import uvicorn

    app = create_app(settings or Settings())
    uvicorn.run(app, host=host, port=port, log_level="info")
