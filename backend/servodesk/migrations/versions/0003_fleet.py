"""The fleet: gateways, one row per drive (plant tag, approved backup, drift state) and the
drift checks' results (issue 49, second slice; services/fleet.py, docs/deployment.md).

``fleet_drives`` is filled from ``backups`` by the fleet service itself (its first sync after
this revision reads every backup once), not here: the revision only makes the tables.

Revision ID: 0003
Revises: 0002
Create Date: 2026-12-07
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

revision = "0003"
down_revision = "0002"
branch_labels = None
depends_on = None


def upgrade() -> None:
    op.create_table(
        "gateways",
        sa.Column("name", sa.Text, primary_key=True),
        sa.Column("url", sa.Text, nullable=False),
        sa.Column("buses", sa.Text, nullable=False, server_default="[]"),
        sa.Column("version", sa.Text, nullable=False, server_default=""),
        sa.Column("started", sa.Float, nullable=False),
        sa.Column("last_seen", sa.Float, nullable=False),
    )
    op.create_table(
        "fleet_drives",
        sa.Column("drive_key", sa.Text, primary_key=True),
        sa.Column("plant_tag", sa.Text, unique=True),
        sa.Column("serial", sa.Text),
        sa.Column("profile_id", sa.Text, nullable=False, server_default=""),
        sa.Column("firmware", sa.Text),
        sa.Column("gateway", sa.Text),
        sa.Column("session", sa.Text),
        sa.Column("seen", sa.Float),
        sa.Column("last_backup", sa.Text),
        sa.Column("last_backup_time", sa.Text),
        sa.Column("last_backup_created", sa.Float),
        sa.Column("approved_backup", sa.Text),
        sa.Column("approved_by", sa.Text),
        sa.Column("approved_at", sa.Text),
        sa.Column("approved_reason", sa.Text),
        sa.Column("drift_state", sa.Text, nullable=False, server_default="unknown"),
        sa.Column("drift_count", sa.Integer),
        sa.Column("drift_time", sa.Text),
        sa.Column("alarms", sa.Integer),
    )
    op.create_index("fleet_drives_drift", "fleet_drives", ["drift_state"])
    op.create_index("fleet_drives_backup_created", "fleet_drives", ["last_backup_created"])
    op.create_table(
        "drift_results",
        sa.Column("id", sa.Integer, primary_key=True, autoincrement=True),
        sa.Column("drive_key", sa.Text, nullable=False),
        sa.Column("time", sa.Text, nullable=False),
        sa.Column("created", sa.Float, nullable=False),
        sa.Column("gateway", sa.Text, nullable=False),
        sa.Column("session", sa.Text, nullable=False),
        sa.Column("backup", sa.Text, nullable=False),
        sa.Column("state", sa.Text, nullable=False),
        sa.Column("count", sa.Integer, nullable=False),
        sa.Column("differences", sa.Text, nullable=False),
        sa.Column("webhook", sa.Text),
        sqlite_autoincrement=True,
    )
    op.create_index("drift_results_drive", "drift_results", ["drive_key", "id"])
    # The fleet's sync reads the backups made since its last look (by ``created``).
    op.create_index("backups_created", "backups", ["created"])
