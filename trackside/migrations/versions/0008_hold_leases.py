"""A vehicle hold is a lease: it expires unless renewed (issue 20, "holds are leases").

The holds stored before get one default lease (60 s) from the migration on: the consoles still
open renew them when they reconnect; the others lapse, and their vehicles are free again.

Revision ID: 0008
Revises: 0007
"""

from datetime import UTC, datetime, timedelta

import sqlalchemy as sa
from alembic import op

revision = "0008"
down_revision = "0007"
branch_labels = None
depends_on = None

FIRST_LEASE_S = 60.0


def upgrade() -> None:
    with op.batch_alter_table("vehicle_holds") as batch:
        batch.add_column(sa.Column("expires_at", sa.DateTime(timezone=True), nullable=True))
    holds = sa.table("vehicle_holds", sa.column("expires_at", sa.DateTime(timezone=True)))
    op.execute(
        holds.update().values(expires_at=datetime.now(UTC) + timedelta(seconds=FIRST_LEASE_S))
    )
    with op.batch_alter_table("vehicle_holds") as batch:
        batch.alter_column("expires_at", existing_type=sa.DateTime(timezone=True), nullable=False)


def downgrade() -> None:
    with op.batch_alter_table("vehicle_holds") as batch:
        batch.drop_column("expires_at")
