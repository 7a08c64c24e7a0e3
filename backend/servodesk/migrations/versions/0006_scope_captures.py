"""Scope captures the user keeps (issue 49, "Plant scale": scope captures live in the store;
services/capture_store.py, docs/scope.md "Kept captures"): one row per kept capture, with its
channels' samples as JSON, so that another gateway, a restart and the drive's commissioning
report still have it.

Revision ID: 0006
Revises: 0005
Create Date: 2026-12-07
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

revision = "0006"
down_revision = "0005"
branch_labels = None
depends_on = None


def upgrade() -> None:
    op.create_table(
        "scope_captures",
        sa.Column("id", sa.Text, primary_key=True),
        sa.Column("drive_key", sa.Text, nullable=False),
        sa.Column("session", sa.Text, nullable=False),
        sa.Column("gateway", sa.Text, nullable=False),
        sa.Column("title", sa.Text, nullable=False),
        sa.Column("note", sa.Text, nullable=False, server_default=""),
        sa.Column("time", sa.Text, nullable=False),
        sa.Column("created", sa.Float, nullable=False),
        sa.Column("by", sa.Text, nullable=False),
        sa.Column("client", sa.Text, nullable=False),
        sa.Column("window", sa.Text, nullable=False),
        sa.Column("samples", sa.Integer, nullable=False),
        sa.Column("channels", sa.Text, nullable=False),
        sa.Column("attached", sa.Integer, nullable=False, server_default="0"),
        sa.Column("sha256", sa.Text, nullable=False),
        sa.Column("data", sa.Text, nullable=False),
    )
    op.create_index("scope_captures_drive", "scope_captures", ["drive_key", "created"])
