"""Alembic migrations of the site database, applied by :func:`tourbot.web.db.migrate`."""
