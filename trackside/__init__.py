"""ATO-TS: the trackside service (FastAPI), built by :func:`trackside.main.create_app`.

Layers: ``api/routes`` (HTTP only) → ``services`` (domain rules, domain errors) → ``models`` /
``db`` (SQLAlchemy persistence). The domain errors (``errors``) become HTTP answers in one
place, the app's exception handlers (``api/exception_handlers``). ``bridge`` is the Zenoh side:
liveliness and status of every vehicle. Never imports ``onboard``.
"""

__all__ = []
