"""Tuning results (issue 49, "Plant scale": tuning results live in the store; services/
tuning_store.py, docs/tuning.md): one row per finished tuning job, done, failed or stopped,
with its TuningResult, so that a restart or a second gateway still sees a drive's tunings.

Revision ID: 0005
Revises: 0004
Create Date: 2026-12-07
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

revision = "0005"
down_revision = "0004"
branch_labels = None
depends_on = None


def upgrade() -> None:
    op.create_table(
        "tuning_results",
        sa.Column("id", sa.Text, primary_key=True),
        sa.Column("drive_key", sa.Text, nullable=False),
        sa.Column("session", sa.Text, nullable=False),
        sa.Column("gateway", sa.Text, nullable=False),
        sa.Column("kind", sa.Text, nullable=False),
        sa.Column("mode", sa.Text, nullable=False),
        sa.Column("status", sa.Text, nullable=False),
        sa.Column("started", sa.Float, nullable=False),
        sa.Column("ended", sa.Float, nullable=False),
        sa.Column("by", sa.Text, nullable=False),
        sa.Column("client", sa.Text, nullable=False),
        sa.Column("applied", sa.Integer, nullable=False),
        sa.Column("result", sa.Text, nullable=False),
    )
    op.create_index("tuning_results_drive", "tuning_results", ["drive_key", "ended"])
