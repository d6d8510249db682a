"""Alembic revisions, numbered 0001, 0002, …; each names the previous one as `down_revision`."""
