"""Vehicle holds, the audit log, the onboard event log and the 1 Hz telemetry history.

Revision ID: 0004
Revises: 0003
"""

import sqlalchemy as sa
from alembic import op

revision = "0004"
down_revision = "0003"
branch_labels = None
depends_on = None


def upgrade() -> None:
    op.create_table(
        "vehicle_holds",
        sa.Column("vehicle_id", sa.String(32), primary_key=True),
        sa.Column("username", sa.String(64), nullable=False),
        sa.Column("since", sa.DateTime(timezone=True), nullable=False),
    )
    op.create_table(
        "audit_log",
        sa.Column("id", sa.Integer, primary_key=True),
        sa.Column("at", sa.DateTime(timezone=True), nullable=False),
        sa.Column("username", sa.String(64), nullable=False),
        sa.Column("vehicle_id", sa.String(32), nullable=True, index=True),
        sa.Column("action", sa.String(64), nullable=False),
        sa.Column("request", sa.Text, nullable=False),
        sa.Column("result", sa.String(16), nullable=False),
        sa.Column("detail", sa.Text, nullable=True),
    )
    op.create_table(
        "vehicle_events",
        sa.Column("id", sa.Integer, primary_key=True),
        sa.Column("vehicle_id", sa.String(32), nullable=False, index=True),
        sa.Column("seq", sa.Integer, nullable=False),
        sa.Column("sim_time_s", sa.Float, nullable=False),
        sa.Column("received_at", sa.DateTime(timezone=True), nullable=False),
        sa.Column("severity", sa.String(16), nullable=False),
        sa.Column("code", sa.String(64), nullable=False),
        sa.Column("text", sa.Text, nullable=False),
    )
    op.create_table(
        "telemetry",
        sa.Column("id", sa.Integer, primary_key=True),
        sa.Column("vehicle_id", sa.String(32), nullable=False, index=True),
        sa.Column("sim_time_s", sa.Float, nullable=False),
        sa.Column("received_at", sa.DateTime(timezone=True), nullable=False),
        sa.Column("position_m", sa.Float, nullable=False),
        sa.Column("speed_mps", sa.Float, nullable=False),
        sa.Column("traction_force_n", sa.Float, nullable=False),
        sa.Column("reference_speed_mps", sa.Float, nullable=True),
        sa.Column("permitted_speed_mps", sa.Float, nullable=True),
        sa.Column("intervention_speed_mps", sa.Float, nullable=True),
        sa.Column("ato_state", sa.String(16), nullable=False),
        sa.Column("etcs_mode", sa.String(16), nullable=False),
        sa.Column("sc_state", sa.String(16), nullable=False),
        sa.Column("eb", sa.Boolean, nullable=False),
        sa.Column("journey_id", sa.String(64), nullable=True),
    )


def downgrade() -> None:
    op.drop_table("telemetry")
    op.drop_table("vehicle_events")
    op.drop_table("audit_log")
    op.drop_table("vehicle_holds")
