"""Alembic environment: runs on the connection that :func:`tourbot.web.db.migrate` hands over."""

from __future__ import annotations

from alembic import context

from tourbot.web.db import Base

connection = context.config.attributes["connection"]
context.configure(connection=connection, target_metadata=Base.metadata, render_as_batch=True)
with context.begin_transaction():
    context.run_migrations()
