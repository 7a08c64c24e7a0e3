"""The store's schema revisions (Alembic), run by :func:`servodesk.services.db.upgrade`
whenever a store is opened. A new revision: ``versions/NNNN_what.py`` with ``down_revision``
the previous one; never edit a revision that has shipped."""
