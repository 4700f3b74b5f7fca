"""Lines: every imported version (``line_versions``) and the current one of each id (``lines``).

Revision ID: 0002
Revises: 0001
"""

import sqlalchemy as sa
from alembic import op

revision = "0002"
down_revision = "0001"
branch_labels = None
depends_on = None


def upgrade() -> None:
    op.create_table(
        "line_versions",
        sa.Column("id", sa.Integer, primary_key=True),
        sa.Column("line_id", sa.String(64), nullable=False),
        sa.Column("version", sa.String(64), nullable=False),
        sa.Column("schema_version", sa.Integer, nullable=False),
        sa.Column("name", sa.String(128), nullable=False),
        sa.Column("length_m", sa.Float, nullable=False),
        sa.Column("ring", sa.Boolean, nullable=False),
        sa.Column("etcs_level", sa.Integer, nullable=False),
        sa.Column("document", sa.Text, nullable=False),
        sa.Column("created_at", sa.DateTime(timezone=True), nullable=False),
        sa.UniqueConstraint("line_id", "version", name="uq_line_versions_line_version"),
    )
    op.create_table(
        "lines",
        sa.Column("id", sa.String(64), primary_key=True),
        sa.Column("version", sa.String(64), nullable=False),
        sa.Column("updated_at", sa.DateTime(timezone=True), nullable=False),
        sa.ForeignKeyConstraint(
            ["id", "version"],
            ["line_versions.line_id", "line_versions.version"],
            name="fk_lines_current_version",
        ),
    )


def downgrade() -> None:
    op.drop_table("lines")
    op.drop_table("line_versions")
