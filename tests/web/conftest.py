"""Database URLs for the web tests: SQLite always, PostgreSQL when CI provides one."""

from __future__ import annotations

import os
import shutil
from collections.abc import Iterator
from pathlib import Path

import pytest
from sqlalchemy import create_engine, text

from tourbot.web.db import Database

_PG = os.environ.get("TOURBOT_TEST_DATABASE_URL")
_BACKENDS = [
    pytest.param("sqlite", id="sqlite"),
    pytest.param(
        "postgresql",
        id="postgresql",
        marks=[
            pytest.mark.postgres,
            pytest.mark.skipif(not _PG, reason="TOURBOT_TEST_DATABASE_URL not set (CI sets it)"),
        ],
    ),
]


def _empty_postgres(url: str) -> str:
    engine = create_engine(url)
    with engine.begin() as conn:
        conn.execute(text("DROP SCHEMA IF EXISTS public CASCADE"))
        conn.execute(text("CREATE SCHEMA public"))
    engine.dispose()
    return url


@pytest.fixture(params=_BACKENDS)
def database_url(request: pytest.FixtureRequest, tmp_path: Path) -> Iterator[str]:
    """An empty database, on each backend."""
    if request.param == "sqlite":
        yield f"sqlite:///{tmp_path / 'site.db'}"
    else:
        assert _PG is not None
        yield _empty_postgres(_PG)


@pytest.fixture(scope="session")
def _migrated_sqlite(tmp_path_factory: pytest.TempPathFactory) -> Path:
    from tourbot.web.db import open_database

    path = tmp_path_factory.mktemp("template") / "site.db"
    open_database(f"sqlite:///{path}").engine.dispose()
    return path


@pytest.fixture
def sqlite_url(tmp_path: Path, _migrated_sqlite: Path) -> str:
    """An empty SQLite site database, already migrated (a copy: migrating takes a second)."""
    shutil.copyfile(_migrated_sqlite, tmp_path / "site.db")
    return f"sqlite:///{tmp_path / 'site.db'}"


@pytest.fixture
def db(sqlite_url: str) -> Database:
    """A small site: two exhibits, one tour, one staff login (curator / correct horse)."""
    from tourbot.web.db import open_database

    db = open_database(sqlite_url)
    db.save_exhibit("amphora", "Amphora", x=4.0, y=2.0, summary="A clay amphora.")
    db.save_exhibit("loom", "Loom", x=6.0, y=4.0)
    db.save_tour("short", "Short tour", ["amphora", "loom"])
    db.set_staff("curator", "correct horse")
    return db
