"""The ATO-TS application: ``create_app(settings)`` and the ``main()`` that serves it."""

from __future__ import annotations

import gc
import logging
import sys
import time
from collections.abc import AsyncIterator, Callable
from contextlib import (
    AbstractAsyncContextManager,
    AbstractContextManager,
    asynccontextmanager,
    nullcontext,
)
from functools import partial
from importlib import resources
from pathlib import Path

import zenoh
from fastapi import APIRouter, FastAPI
from fastapi.responses import FileResponse
from fastapi.staticfiles import StaticFiles
from sqlalchemy import Engine
from sqlalchemy.orm import Session, sessionmaker

from protocol import messages as m
from protocol import open_session
from protocol.messages import StatusReport
from trackdb import LineNotFoundError
from trackdb.headway import HeadwayRule
from trackdb.storage import current_version, line_versions
from trackside.api.exception_handlers import add_exception_handlers
from trackside.api.routes import audit as audit_routes
from trackside.api.routes import auth, journeys, lines, rbc, vehicles, ws
from trackside.api.routes import users as users_routes
from trackside.bridge import ZenohBridge
from trackside.config import Settings
from trackside.db import create_database_engine, migrate
from trackside.edge import EdgeMiddleware, content_security_policy, inline_style_hashes
from trackside.journey_planner import JourneyPlanner
from trackside.live import LiveHub
from trackside.log_redaction import install_token_redaction
from trackside.metrics import add_metrics
from trackside.models import AuditEntry, Role
from trackside.ratelimit import LoginLimiter
from trackside.rbc import LineInfo, RbcEmulator
from trackside.rbc_persistence import RbcPersistence
from trackside.rbc_scenario import (
    RbcScenario,
    RbcScenarioRunner,
    RbcScenarioThread,
    load_scenario,
)
from trackside.recorder import Recorder
from trackside.separation import MovingBlock
from trackside.separation_supervisor import SeparationSupervisor
from trackside.services import audit, users
from trackside.services import lines as lines_service
from trackside.services.commands import CommandService
from trackside.services.fleet_list import FleetListCache
from trackside.simulated_operator import (
    SIMULATED_OPERATOR,
    OperatorAnswer,
    SimulatedOperator,
    SimulatedOperatorThread,
)

__all__ = ["create_app", "main"]

Lifespan = Callable[[FastAPI], AbstractAsyncContextManager[None]]
"""What FastAPI runs around the service's life: start-up before ``yield``, shutdown after."""

_log = logging.getLogger(__name__)


SWITCH_INTERVAL_S = 0.0005
"""How long a thread holds the interpreter while another waits for it [s] (Python's default is
5 ms). A request gives the interpreter up at each database call and socket write, and takes it
back only when the thread validating 5 000 status reports a second lets it go: at 5 ms a time,
a command of some twenty such calls waited up to 100 ms (docs/trackside.md, "Benchmark")."""

GC_THRESHOLDS = (20_000, 10, 10)
"""The cyclic collector's thresholds while the service runs (Python's are 700, 10, 10): a
young collection every 20 000 new container objects, not 700. A thousand vehicles' reports
made one every 50 ms, each a pause of every thread (0.5 ms typical, up to 12 ms; the older
generations' up to 18 ms): at 20 000 one every second or two, and the service's REST p99 at a
thousand vehicles fell from 60 to 47 ms (docs/trackside.md, "Fourth sitting")."""


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


def _line_document(factory: sessionmaker[Session], line_id: str) -> tuple[str, str] | None:
    """The canonical JSON and version of a stored line, for an onboard that lacks them."""
    with factory() as db:
        try:
            return lines_service.line_document(db, line_id)
        except LineNotFoundError:
            return None


def _line_info(factory: sessionmaker[Session], line_id: str) -> LineInfo | None:
    """The current version and extent of a stored line, for the RBC's checks."""
    with factory() as db:
        try:
            summaries = line_versions(db, line_id)
        except LineNotFoundError:
            return None
    for summary in summaries:
        if summary.current:
            return LineInfo(version=summary.version, length_m=summary.length_m, ring=summary.ring)
    return None


def _reported_status(bridge: ZenohBridge, vehicle_id: str) -> StatusReport | None:
    """The vehicle's latest status while it is alive, for the RBC's position checks."""
    snapshot = bridge.snapshot(vehicle_id)
    return None if snapshot is None else snapshot.status


def _seed_lines(settings: Settings, factory: sessionmaker[Session]) -> None:
    if settings.seed_lines:
        with factory() as db, db.begin():
            imported = lines_service.ensure_seed_lines(db)
        if imported:
            _log.info("imported seed lines: %s", ", ".join(imported))


def _plotly_js() -> Path:
    """Where the installed ``plotly`` wheel keeps its browser bundle."""
    bundle = resources.files("plotly") / "package_data" / "plotly.min.js"
    return Path(str(bundle))


def _console_policy() -> str:
    """The Content-Security-Policy, letting in the stylesheets the charting library inserts
    (by their hashes, read from the bundle served)."""
    bundle = _plotly_js()
    hashes = inline_style_hashes(bundle.read_text()) if bundle.is_file() else ()
    return content_security_policy(hashes)


def _operator_entry(
    command: m.Command, result: audit.AuditResult, detail: str | None = None
) -> AuditEntry:
    """An audit entry of a simulated operator's command; intent and outcome share its id."""
    request = command.body.model_dump(mode="json")
    return audit.audit_entry(
        user=SIMULATED_OPERATOR,
        vehicle_id=command.vehicle_id,
        action=audit.command_action(command.body),
        request=request | {"request_id": command.command_id, "command_id": command.command_id},
        result=result,
        detail=detail,
    )


def _send_operator_command(
    bridge: ZenohBridge,
    recorder: Recorder,
    timeout_s: float,
    command: m.Command,
    on_done: Callable[[m.CommandAck | None], None],
) -> None:
    """Queue the intent's audit entry, then send (on the operator's thread; never waits on the
    database: the recorder's audit writer never drops an entry)."""
    recorder.offer(_operator_entry(command, audit.AuditResult.REQUESTED))
    # A ProtocolError goes to the operator, which answers it as no acknowledgement (the
    # outcome's entry, by _audit_answer).
    bridge.command_async(command, on_done, timeout_s=timeout_s)


def _audit_answer(recorder: Recorder, answer: OperatorAnswer) -> None:
    """Queue the outcome's audit entry of a simulated operator's answer (on Zenoh's thread)."""
    ack = answer.ack
    result = (
        audit.AuditResult.TIMEOUT
        if ack is None
        else audit.AuditResult.ACCEPTED
        if ack.accepted
        else audit.AuditResult.REFUSED
    )
    recorder.offer(_operator_entry(answer.command, result, None if ack is None else ack.reason))


def _simulated_operator(
    settings: Settings, bridge: ZenohBridge, recorder: Recorder
) -> SimulatedOperatorThread | None:
    if not settings.simulated_operators:
        return None
    operator = SimulatedOperator(
        partial(_send_operator_command, bridge, recorder, settings.command_timeout_s),
        settings.simulated_operators,
        reaction_s=settings.simulated_operator_reaction_s,
        kinds=settings.simulated_operator_kinds,
        on_answer=partial(_audit_answer, recorder),
        first_command_id=time.time_ns() // 1000,
    )
    return SimulatedOperatorThread(
        operator, partial(_reported_status, bridge), start=settings.simulated_operator_thread
    )


def _prepare_database(settings: Settings, engine: Engine) -> sessionmaker[Session]:
    """Migrate the database, then add the bootstrap admin and the seed lines it lacks."""
    migrate(engine)
    factory = sessionmaker(engine, expire_on_commit=False)
    _bootstrap_admin(settings, factory)
    _seed_lines(settings, factory)
    return factory


def _open_zenoh(
    settings: Settings, zenoh_session: zenoh.Session | None
) -> AbstractContextManager[zenoh.Session]:
    """The session given (left open at the end), else one of the service's own."""
    if zenoh_session is not None:
        return nullcontext(zenoh_session)
    return open_session(settings.zenoh())


def _start_bridge(
    app: FastAPI,
    settings: Settings,
    session: zenoh.Session,
    factory: sessionmaker[Session],
    recorder: Recorder,
    hub: LiveHub,
) -> ZenohBridge:
    """The Zenoh bridge, its telemetry fanned out to the recorder and the browsers."""
    bridge = ZenohBridge(
        session,
        instance_id=settings.instance_id,
        line_version=lambda line_id: _line_version(factory, line_id),
        line_document=lambda line_id: _line_document(factory, line_id),
        status_intake_s=settings.status_intake_period_s or None,
    )
    app.state.bridge = bridge
    app.state.fleet_list = FleetListCache()
    bridge.observe(status=recorder.offer_status, event=recorder.offer_event)
    bridge.observe(status=hub.publish_status, event=hub.publish_event)
    app.state.commands = CommandService(
        factory,
        bridge,
        timeout_s=settings.command_timeout_s,
        hold_lease_s=settings.hold_lease_s,
    )
    return bridge


def _start_rbc(
    app: FastAPI,
    session: zenoh.Session,
    factory: sessionmaker[Session],
    bridge: ZenohBridge,
    script: RbcScenario | None,
) -> tuple[RbcEmulator, RbcScenarioThread | None]:
    """The RBC emulator on the service's clock, and the thread of its scenario if one is set."""
    started_s = time.monotonic()
    rbc_emulator = RbcEmulator(
        clock=lambda: time.monotonic() - started_s,
        session=session,
        line_info=partial(_line_info, factory),
        positions=partial(_reported_status, bridge),
        seal=bridge.seal,
        persistence=RbcPersistence(factory),
    )
    app.state.rbc = rbc_emulator
    scenario = None
    if script is not None:
        scenario = RbcScenarioThread(RbcScenarioRunner(script, rbc_emulator))
    return rbc_emulator, scenario


def _start_separation(
    app: FastAPI,
    settings: Settings,
    factory: sessionmaker[Session],
    bridge: ZenohBridge,
    rbc_emulator: RbcEmulator,
) -> None:
    """The RBC's separation of the trains on a line, when ``separation_margin_m`` is set: fed
    with every report of an open session before it is acknowledged, the train's length from its
    handshake; and the planning of their journeys against each other's."""
    app.state.separation = None
    if settings.separation_margin_m is None:
        return
    ring_lengths = _ring_lengths(factory)
    block = MovingBlock(margin_m=settings.separation_margin_m, ring_length_m=ring_lengths)
    app.state.commands.planner = JourneyPlanner(
        HeadwayRule(margin_m=settings.separation_margin_m),
        mode=settings.journey_planning,
        fleet=bridge.fleet,
        lengths=bridge.train_length_m,
        ring_length_m=ring_lengths,
        max_delay_s=settings.journey_planning_max_delay_s,
    )
    supervisor = SeparationSupervisor(
        rbc_emulator,
        block,
        extension_step_m=settings.separation_extension_step_m,
        lengths=bridge.train_length_m,
    )
    app.state.separation = supervisor

    def supervise(report: StatusReport) -> None:
        try:
            supervisor.on_report(report, rbc_emulator.clock())
        except Exception:  # an MA change refused or not published: the next report tries again
            _log.exception("separation: the report of %s was not taken", report.vehicle_id)

    bridge.supervise_reports(supervise)


def _ring_lengths(factory: sessionmaker[Session]) -> Callable[[str], float | None]:
    """Each line's length if it is a ring, read once per stored line (the separation asks for
    it on every report; a line not stored yet is asked for again)."""
    known: dict[str, float | None] = {}

    def ring_length_m(line_id: str) -> float | None:
        if line_id not in known:
            info = _line_info(factory, line_id)
            if info is None:
                return None
            known[line_id] = info.length_m if info.ring else None
        return known[line_id]

    return ring_length_m


def _lifespan(settings: Settings, zenoh_session: zenoh.Session | None) -> Lifespan:
    """Start-up and shutdown of the service: the database, Zenoh, the bridge, the RBC."""

    @asynccontextmanager
    async def lifespan(app: FastAPI) -> AsyncIterator[None]:
        install_token_redaction()  # after uvicorn has set its logging up
        script = None if settings.rbc_scenario is None else load_scenario(settings.rbc_scenario)
        engine = create_database_engine(settings.database_url)
        factory = _prepare_database(settings, engine)
        app.state.settings = settings
        app.state.session_factory = factory
        app.state.login_limiter = LoginLimiter(
            max_failures=settings.login_max_failures, window_s=settings.login_window_s
        )
        recorder = Recorder(factory, capacity=settings.recorder_capacity)
        app.state.recorder = recorder
        hub = LiveHub()
        app.state.live = hub
        with _open_zenoh(settings, zenoh_session) as session:
            bridge = _start_bridge(app, settings, session, factory, recorder, hub)
            operator = _simulated_operator(settings, bridge, recorder)
            app.state.simulated_operator = operator
            rbc_emulator, scenario = _start_rbc(app, session, factory, bridge, script)
            _start_separation(app, settings, factory, bridge, rbc_emulator)
            # What start-up built lives as long as the service: keep it out of the cyclic
            # collector's full passes, which otherwise stall requests for tens of ms.
            gc.freeze()
            switch_interval_s, thresholds = sys.getswitchinterval(), gc.get_threshold()
            sys.setswitchinterval(SWITCH_INTERVAL_S)
            gc.set_threshold(*GC_THRESHOLDS)
            try:
                yield
            finally:
                sys.setswitchinterval(switch_interval_s)
                gc.set_threshold(*thresholds)
                if scenario is not None:
                    scenario.close()
                if operator is not None:
                    operator.close()
                rbc_emulator.close()
                bridge.close()
                recorder.close()
                engine.dispose()

    return lifespan


def _api_router() -> APIRouter:
    """Every resource's routes, under ``/api/v1``."""
    api = APIRouter(prefix="/api/v1")
    api.include_router(auth.router)
    api.include_router(users_routes.router)
    api.include_router(vehicles.router)
    api.include_router(lines.router)
    api.include_router(journeys.router)
    api.include_router(rbc.router)
    api.include_router(audit_routes.router)
    api.include_router(ws.router)
    return api


def _add_health_route(app: FastAPI) -> None:
    @app.get("/healthz", tags=["health"])
    def health() -> dict[str, str]:
        """Liveness of the service itself (no authentication)."""
        return {"status": "ok"}


def _add_web_console(app: FastAPI, webui: Path) -> None:
    """Serve the web console's static files, when the directory is there."""
    if not webui.is_dir():
        return
    app.mount("/static", StaticFiles(directory=webui), name="static")

    @app.get("/", include_in_schema=False)
    def index() -> FileResponse:
        return FileResponse(webui / "index.html")

    @app.get("/vendor/plotly.min.js", include_in_schema=False)
    def plotly_js() -> FileResponse:
        """The charting library, as its PyPI wheel ships it (not copied into the repo)."""
        return FileResponse(_plotly_js(), media_type="text/javascript")


def create_app(settings: Settings, *, zenoh_session: zenoh.Session | None = None) -> FastAPI:
    """Build the service. Without ``zenoh_session`` it opens (and closes) its own."""
    app = FastAPI(
        title="ATO-TS",
        summary="Trackside service of the ato GoA4 ATO over ETCS stack",
        version="0.1.0",
        lifespan=_lifespan(settings, zenoh_session),
    )
    add_exception_handlers(app)
    app.add_middleware(
        EdgeMiddleware, max_body_bytes=settings.max_body_bytes, policy=_console_policy()
    )
    app.include_router(_api_router())
    _add_health_route(app)
    add_metrics(
        app,
        token=lambda: (
            None if settings.metrics_token is None else settings.metrics_token.get_secret_value()
        ),
    )
    _add_web_console(app, settings.webui_dir)
    return app


def main(settings: Settings | None = None, *, host: str = "127.0.0.1", port: int = 8000) -> None:
    """Serve ATO-TS with uvicorn until interrupted."""
    import uvicorn

    app = create_app(settings or Settings())
    uvicorn.run(app, host=host, port=port, log_level="info")
