"""Backups' content in the store: one row per distinct content, keyed by its SHA-256.

Before, a backup's bytes lived only in ``<data_dir>/backups/``; a second machine on the same
store could list the backup but not open it. The files of an existing data directory are
copied in by :class:`servodesk.services.store.Store` when it opens (the files are not the
database's to read here).

Revision ID: 0002
Revises: 0001
Create Date: 2026-12-07
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

revision = "0002"
down_revision = "0001"
branch_labels = None
depends_on = None


def upgrade() -> None:
    op.create_table(
        "backup_content",
        sa.Column("sha256", sa.Text, primary_key=True),
        sa.Column("size", sa.Integer, nullable=False),
        sa.Column("data", sa.LargeBinary, nullable=False),
    )
