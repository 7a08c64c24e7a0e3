"""The schema of servodesk's SQLite store as it was before issue 49.

A data directory made by an earlier servodesk already has these tables (made with
``CREATE TABLE IF NOT EXISTS`` and no revision): this revision creates only what is
missing, so it takes such a database in place. The ``unreadable`` column of ``backups``
(issue 48) came later than the table: an older table gets it here.

Revision ID: 0001
Revises:
Create Date: 2026-12-07
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

revision = "0001"
down_revision = None
branch_labels = None
depends_on = None

meta = sa.MetaData()

sa.Table(
    "backups",
    meta,
    sa.Column("id", sa.Text, primary_key=True),
    sa.Column("time", sa.Text, nullable=False),
    sa.Column("created", sa.Float, nullable=False),
    sa.Column("label", sa.Text, nullable=False, server_default=""),
    sa.Column("note", sa.Text, nullable=False, server_default=""),
    sa.Column("profile_id", sa.Text, nullable=False),
    sa.Column("profile_version", sa.Text, nullable=False, server_default=""),
    sa.Column("drive_key", sa.Text, nullable=False),
    sa.Column("identity", sa.Text, nullable=False),
    sa.Column("firmware", sa.Text),
    sa.Column("bus", sa.Text, nullable=False),
    sa.Column("entries", sa.Integer, nullable=False),
    sa.Column("file", sa.Text, nullable=False),
    sa.Column("sha256", sa.Text, nullable=False),
    sa.Column("source", sa.Text, nullable=False, server_default="drive"),
    sa.Column("unreadable", sa.Text),
    sa.Index("backups_drive", "drive_key", "created"),
)
sa.Table(
    "restores",
    meta,
    sa.Column("id", sa.Text, primary_key=True),
    sa.Column("backup", sa.Text, nullable=False),
    sa.Column("session", sa.Text, nullable=False),
    sa.Column("drive_key", sa.Text, nullable=False),
    sa.Column("bus", sa.Text, nullable=False),
    sa.Column("time", sa.Text, nullable=False),
    sa.Column("created", sa.Float, nullable=False),
    sa.Column("dry_run", sa.Integer, nullable=False),
    sa.Column("finished", sa.Integer, nullable=False, server_default="0"),
    sa.Column("stored", sa.Integer, nullable=False, server_default="0"),
    sa.Column("interrupted", sa.Integer, nullable=False, server_default="0"),
    sa.Column("pre_backup", sa.Text),
    sa.Column("options", sa.Text, nullable=False),
    sa.Column("message", sa.Text),
)
sa.Table(
    "restore_items",
    meta,
    sa.Column("restore", sa.Text, primary_key=True),
    sa.Column("seq", sa.Integer, primary_key=True, autoincrement=False),
    sa.Column("address", sa.Text, nullable=False),
    sa.Column("source", sa.Text, nullable=False),
    sa.Column("name", sa.Text, nullable=False),
    sa.Column("status", sa.Text, nullable=False),
    sa.Column("old_raw_hex", sa.Text),
    sa.Column("new_raw_hex", sa.Text),
    sa.Column("code", sa.Integer),
    sa.Column("meaning", sa.Text),
    sa.Column("message", sa.Text),
)
sa.Table(
    "audit",
    meta,
    sa.Column("id", sa.Integer, primary_key=True, autoincrement=True),
    sa.Column("time", sa.Float, nullable=False),
    sa.Column("client", sa.Text, nullable=False),
    sa.Column("session", sa.Text, nullable=False),
    sa.Column("drive_key", sa.Text, nullable=False),
    sa.Column("address", sa.Text, nullable=False),
    sa.Column("name", sa.Text),
    sa.Column("old_raw_hex", sa.Text),
    sa.Column("new_raw_hex", sa.Text, nullable=False),
    sa.Column("old_value", sa.Text),
    sa.Column("new_value", sa.Text),
    sa.Index("audit_session", "session", "id"),
    sqlite_autoincrement=True,
)
sa.Table(
    "audit_log",
    meta,
    sa.Column("seq", sa.Integer, primary_key=True, autoincrement=False),
    sa.Column("time", sa.Text, nullable=False),
    sa.Column("user", sa.Text, nullable=False),
    sa.Column("address", sa.Text, nullable=False),
    sa.Column("category", sa.Text, nullable=False),
    sa.Column("event", sa.Text, nullable=False),
    sa.Column("drive", sa.Text),
    sa.Column("result", sa.Text, nullable=False),
    sa.Column("message", sa.Text, nullable=False),
    sa.Column("details", sa.Text, nullable=False),
    sa.Column("prev", sa.Text, nullable=False),
    sa.Column("hash", sa.Text, nullable=False),
    sa.Index("audit_log_time", "time"),
)
sa.Table(
    "users",
    meta,
    sa.Column("name", sa.Text, primary_key=True),
    sa.Column("role", sa.Text, nullable=False),
    sa.Column("hash", sa.Text, nullable=False),
    sa.Column("disabled", sa.Integer, nullable=False, server_default="0"),
    sa.Column("created", sa.Float, nullable=False),
)
sa.Table(
    "api_tokens",
    meta,
    sa.Column("id", sa.Text, primary_key=True),
    sa.Column("user", sa.Text, nullable=False),
    sa.Column("label", sa.Text, nullable=False, server_default=""),
    sa.Column("sha256", sa.Text, nullable=False),
    sa.Column("created", sa.Float, nullable=False),
    sa.Column("last_used", sa.Float),
    sa.Index("api_tokens_user", "user"),
)

# The audit log is append-only (IEC 62443-4-2 CR 3.9; services/audit.py): the database
# itself refuses UPDATE and DELETE, whoever connects.
SQLITE_TRIGGERS = [
    "CREATE TRIGGER IF NOT EXISTS audit_log_no_update BEFORE UPDATE ON audit_log "
    "BEGIN SELECT RAISE(ABORT, 'the audit log is append-only'); END",
    "CREATE TRIGGER IF NOT EXISTS audit_log_no_delete BEFORE DELETE ON audit_log "
    "BEGIN SELECT RAISE(ABORT, 'the audit log is append-only'); END",
]
POSTGRES_TRIGGERS = [
    "CREATE OR REPLACE FUNCTION audit_log_append_only() RETURNS trigger LANGUAGE plpgsql AS "
    "$$ BEGIN RAISE EXCEPTION 'the audit log is append-only'; END $$",
    "DROP TRIGGER IF EXISTS audit_log_no_change ON audit_log",
    "CREATE TRIGGER audit_log_no_change BEFORE UPDATE OR DELETE OR TRUNCATE ON audit_log "
    "FOR EACH STATEMENT EXECUTE FUNCTION audit_log_append_only()",
]


def upgrade() -> None:
    bind = op.get_bind()
    meta.create_all(bind, checkfirst=True)
    columns = {c["name"] for c in sa.inspect(bind).get_columns("backups")}
    if "unreadable" not in columns:
        op.add_column("backups", sa.Column("unreadable", sa.Text))
    for statement in SQLITE_TRIGGERS if bind.dialect.name == "sqlite" else POSTGRES_TRIGGERS:
        op.execute(statement)
