"""Commissioning reports (issue 49, "Commissioning report"; services/report_store.py,
docs/report.md): one row per report made, with its content hash, its HTML and its PDF.

Revision ID: 0004
Revises: 0003
Create Date: 2026-12-07
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

revision = "0004"
down_revision = "0003"
branch_labels = None
depends_on = None


def upgrade() -> None:
    op.create_table(
        "reports",
        sa.Column("id", sa.Text, primary_key=True),
        sa.Column("drive_key", sa.Text, nullable=False),
        sa.Column("plant_tag", sa.Text),
        sa.Column("session", sa.Text, nullable=False),
        sa.Column("time", sa.Text, nullable=False),
        sa.Column("created", sa.Float, nullable=False),
        sa.Column("by", sa.Text, nullable=False),
        sa.Column("sha256", sa.Text, nullable=False),
        sa.Column("html", sa.LargeBinary, nullable=False),
        sa.Column("html_sha256", sa.Text, nullable=False),
        sa.Column("pdf", sa.LargeBinary),
        sa.Column("pdf_sha256", sa.Text),
    )
    op.create_index("reports_drive", "reports", ["drive_key", "created"])
