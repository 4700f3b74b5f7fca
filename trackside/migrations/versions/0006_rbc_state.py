"""The RBC's state kept across restarts: each vehicle's MA counter and MA in force, and the TSRs
in force (issue 20, "durable RBC").

Revision ID: 0006
Revises: 0005
"""

import sqlalchemy as sa
from alembic import op

revision = "0006"
down_revision = "0005"
branch_labels = None
depends_on = None


def upgrade() -> None:
    op.create_table(
        "rbc_movement_authorities",
        sa.Column("vehicle_id", sa.String(32), primary_key=True),
        sa.Column("last_ma_id", sa.Integer, nullable=False),
        sa.Column("message", sa.Text, nullable=True),
        sa.Column("updated_at", sa.DateTime(timezone=True), nullable=False),
    )
    op.create_table(
        "rbc_speed_restrictions",
        sa.Column("vehicle_id", sa.String(32), primary_key=True),
        sa.Column("restriction_id", sa.String(64), primary_key=True),
        sa.Column("message", sa.Text, nullable=False),
        sa.Column("issued_at", sa.DateTime(timezone=True), nullable=False),
    )


def downgrade() -> None:
    op.drop_table("rbc_speed_restrictions")
    op.drop_table("rbc_movement_authorities")
