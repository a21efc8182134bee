from __future__ import annotations

import pytest
from sqlalchemy import text

from tourbot.web.db import Database, DatabaseError, migrate, open_database


def test_content_round_trip(database_url: str) -> None:
    db = open_database(database_url)
    db.save_exhibit(
        "amphora", "Amphora", x=1.0, y=2.0, theta=0.5, text="Clay.",
        pictures=[("/pics/a.jpg", "front")], links=[("https://example.org/a", "more")],
    )  # fmt: skip
    db.save_exhibit("chiton", "Chiton", x=4.0, y=-1.0)
    tour = db.save_tour("short", "Short tour", ["chiton", "amphora"])
    assert tour.exhibits == ("chiton", "amphora")
    got = db.exhibit("amphora")
    assert (got.x, got.y, got.theta) == (1.0, 2.0, 0.5)
    assert got.pictures == (("/pics/a.jpg", "front"),)
    assert got.links == (("https://example.org/a", "more"),)
    moved = db.place_exhibit("amphora", 3.0, 3.5)
    assert (moved.x, moved.y, moved.theta) == (3.0, 3.5, 0.5)
    db.save_tour("short", "Short tour", ["amphora"])
    assert db.tour("short").exhibits == ("amphora",)
    db.delete_exhibit("amphora")
    assert db.tour("short").exhibits == ()
    with pytest.raises(DatabaseError, match="no exhibit"):
        db.exhibit("amphora")
    with pytest.raises(DatabaseError, match="no exhibit"):
        db.save_tour("bad", "Bad", ["nowhere"])


def test_sessions_bookings_visits_and_staff(database_url: str) -> None:
    db = open_database(database_url)
    db.save_exhibit("amphora", "Amphora", x=1.0, y=2.0)
    robot = db.robot_id("lefkos", "fhw")
    assert db.robot_id("lefkos") == robot
    token, sid = db.new_session()
    found = db.session_for(token)
    assert found is not None
    assert found[0] == sid
    assert db.session_for("forged") is None
    booking = db.booking_started(robot, sid, 10.0)
    db.booking_ended(booking, 70.0, "left")
    assert db.bookings() == [(robot, sid, 10.0, 70.0, "left")]
    db.record_visit("amphora", robot, "web", 20.0)
    db.record_visit("amphora", robot, "onboard", 30.0)
    assert db.visit_counts() == {"amphora": 2}
    db.set_staff("curator", "correct horse")
    assert db.check_staff("curator", "correct horse") is not None
    assert db.check_staff("curator", "wrong horse!") is None
    assert db.check_staff("nobody", "correct horse") is None
    with pytest.raises(DatabaseError, match="8 characters"):
        db.set_staff("curator", "short")
    db.end_session(token)
    assert db.session_for(token) is None


def test_upgrade_keeps_the_content_of_an_old_site(database_url: str) -> None:
    """A site created with the first schema keeps its exhibits after the upgrade to the newest."""
    old = Database(database_url)
    migrate(old.engine, "0001")
    with old.engine.begin() as conn:
        columns = "slug, name, text, x, y, theta"
        conn.execute(text(f"INSERT INTO exhibits ({columns}) VALUES ('vase', 'Vase', 'Old.', 1, 2, 0)"))
    old.engine.dispose()
    db = open_database(database_url)
    got = db.exhibit("vase")
    assert (got.name, got.text, got.summary, got.x) == ("Vase", "Old.", "", 1.0)
    open_database(database_url)  # starting again on an up-to-date schema changes nothing
    assert [e.slug for e in db.exhibits()] == ["vase"]


def test_bad_url_is_a_clear_error() -> None:
    with pytest.raises(DatabaseError, match="cannot"):
        open_database("nosuchdriver://x")


def test_sqlite_takes_concurrent_writers(sqlite_url: str) -> None:
    """20 sessions created at once (20 threads, 20 connections): none fails with "database is
    locked", since the file is in write-ahead-log mode with a busy timeout."""
    import threading

    db = open_database(sqlite_url)
    with db.engine.connect() as connection:
        assert connection.execute(text("PRAGMA journal_mode")).scalar() == "wal"
        assert int(connection.execute(text("PRAGMA busy_timeout")).scalar() or 0) >= 5000
    errors: list[BaseException] = []
    start = threading.Barrier(20)

    def create() -> None:
        start.wait()
        try:
            for _ in range(5):
                token, _ = db.new_session("web")
                assert db.session_for(token) is not None
        except BaseException as exc:  # collected: a thread's failure must fail the test
            errors.append(exc)

    threads = [threading.Thread(target=create) for _ in range(20)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert errors == []
    with db.session() as s:
        from tourbot.web.db import VisitorSession

        assert s.query(VisitorSession).count() == 100


@pytest.mark.parametrize(
    "url",
    ["javascript:alert(1)", "JAVASCRIPT:alert(1)", " javascript:x", "data:text/html,x", "//evil.example",
     "/\\evil.example", "vbscript:x", "java\tscript:x"],
)  # fmt: skip
def test_unsafe_link_urls_are_never_stored(sqlite_url: str, url: str) -> None:
    db = open_database(sqlite_url)
    with pytest.raises(DatabaseError, match="must start with"):
        db.save_exhibit("a", "A", x=0, y=0, links=[(url, "")])
    with pytest.raises(DatabaseError, match="must start with"):
        db.save_exhibit("a", "A", x=0, y=0, pictures=[(url, "")])
    assert db.exhibits() == []
    db.save_exhibit("a", "A", x=0, y=0, links=[("https://example.org/x", ""), ("/static/a.png", "")])
