"""Alembic environment: runs on the connection handed over by ``trackside.db.migrate``.

The target metadata is the trackside's own models and trackdb's tables (lines and their
versions), which trackdb declares on its own base so that it never imports trackside.
"""

from alembic import context

from trackdb.storage import metadata as track_data_metadata
from trackside.models import Base

connection = context.config.attributes.get("connection")
if connection is None:
    raise RuntimeError("run migrations through trackside.db.migrate(engine)")
context.configure(
    connection=connection,
    target_metadata=[Base.metadata, track_data_metadata],
    render_as_batch=connection.dialect.name == "sqlite",
)
with context.begin_transaction():
    context.run_migrations()
