"""ATO-TS: the trackside service (FastAPI), built by :func:`trackside.main.create_app`.

Layers: ``api/routes`` (HTTP only) → ``services`` (domain rules, domain errors) → ``models`` /
``db`` (SQLAlchemy persistence). ``bridge`` is the Zenoh side: liveliness and status of every
vehicle. Never imports ``onboard``.
"""
