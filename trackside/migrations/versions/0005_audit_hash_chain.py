"""The audit log as a hash chain: each entry's SHA-256 over its content and the previous hash,
and the chain's head (the last entry's id and hash), so that a changed, removed or inserted
entry is detected (``ato audit verify``, docs/security.md).

Revision ID: 0005
Revises: 0004
"""

import sqlalchemy as sa
from alembic import op

revision = "0005"
down_revision = "0004"
branch_labels = None
depends_on = None


def upgrade() -> None:
    from trackside.services.audit_chain import GENESIS, entry_hash

    with op.batch_alter_table("audit_log") as batch:
        batch.add_column(sa.Column("prev_hash", sa.String(64), nullable=True))
        batch.add_column(sa.Column("hash", sa.String(64), nullable=True))
    head = op.create_table(
        "audit_chain_head",
        sa.Column("id", sa.Integer, primary_key=True),
        sa.Column("last_id", sa.Integer, nullable=True),
        sa.Column("last_hash", sa.String(64), nullable=False),
    )
    # The entries already there are chained in id order.
    connection = op.get_bind()
    text, name = sa.Text(), sa.String(64)
    log = sa.table(
        "audit_log",
        sa.column("id", sa.Integer()),
        sa.column("at", sa.DateTime(timezone=True)),
        sa.column("username", name),
        sa.column("vehicle_id", name),
        sa.column("action", name),
        sa.column("request", text),
        sa.column("result", name),
        sa.column("detail", text),
        sa.column("prev_hash", name),
        sa.column("hash", name),
    )
    previous, last_id = GENESIS, None
    for row in connection.execute(sa.select(log).order_by(log.c.id)).mappings():
        digest = entry_hash(row, previous)
        connection.execute(
            log.update().where(log.c.id == row["id"]).values(prev_hash=previous, hash=digest)
        )
        previous, last_id = digest, row["id"]
    op.bulk_insert(head, [{"id": 1, "last_id": last_id, "last_hash": previous}])


def downgrade() -> None:
    op.drop_table("audit_chain_head")
    with op.batch_alter_table("audit_log") as batch:
        batch.drop_column("hash")
        batch.drop_column("prev_hash")
