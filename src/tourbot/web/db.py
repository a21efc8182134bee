"""The site's content in a real database (Burgard et al., section 7.1: the "generic multimedia
database" of exhibits, and the task specification saying where the exhibits are).

Tables: robots, exhibits with their media (pictures, links), tours (ordered exhibits), visitor
sessions, control bookings (who held which robot when, and why the slot ended), visits (statistics:
which exhibit was shown, to whom), staff users, and the text messages between the visitor in control
of a robot and the people on site (WebFAIR's tele-conferencing). SQLite by default, PostgreSQL through
``DATABASE_URL``. The schema is owned by the alembic migrations in ``tourbot/web/migrations``,
applied at every start (:func:`open_database`), so an upgrade keeps a site's content.
"""

from __future__ import annotations

import hashlib
import hmac
import os
import secrets
import time
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

from sqlalchemy import (
    Float,
    ForeignKey,
    Index,
    Integer,
    String,
    Text,
    create_engine,
    delete,
    event,
    func,
    select,
)
from sqlalchemy.engine import Engine
from sqlalchemy.orm import DeclarativeBase, Mapped, Session, mapped_column, relationship, sessionmaker

from tourbot.errors import TourbotError

__all__ = [
    "Base",
    "Booking",
    "ChatMessage",
    "Database",
    "DatabaseError",
    "Exhibit",
    "Media",
    "MessageData",
    "Robot",
    "StaffUser",
    "Tour",
    "TourStop",
    "Visit",
    "VisitorSession",
    "check_link_url",
    "check_staff_password",
    "default_url",
    "migrate",
    "open_database",
    "sqlite_file",
]

MIGRATIONS = Path(__file__).with_name("migrations")


class DatabaseError(TourbotError):
    """The site database cannot be opened, or a request on it is wrong (unknown exhibit, ...)."""


class Base(DeclarativeBase):
    pass


class Robot(Base):
    __tablename__ = "robots"
    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    name: Mapped[str] = mapped_column(String(64), unique=True)
    site: Mapped[str] = mapped_column(String(64), default="")


class Exhibit(Base):
    __tablename__ = "exhibits"
    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    slug: Mapped[str] = mapped_column(String(64), unique=True)
    name: Mapped[str] = mapped_column(String(200))
    text: Mapped[str] = mapped_column(Text, default="")
    summary: Mapped[str] = mapped_column(String(400), default="")
    x: Mapped[float] = mapped_column(Float, default=0.0)
    y: Mapped[float] = mapped_column(Float, default=0.0)
    theta: Mapped[float] = mapped_column(Float, default=0.0)
    media: Mapped[list[Media]] = relationship(
        back_populates="exhibit", cascade="all, delete-orphan", order_by="Media.position"
    )


class Media(Base):
    """A picture or a link shown with an exhibit."""

    __tablename__ = "media"
    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    exhibit_id: Mapped[int] = mapped_column(ForeignKey("exhibits.id", ondelete="CASCADE"))
    kind: Mapped[str] = mapped_column(String(16))
    url: Mapped[str] = mapped_column(String(1000))
    caption: Mapped[str] = mapped_column(String(400), default="")
    position: Mapped[int] = mapped_column(Integer, default=0)
    exhibit: Mapped[Exhibit] = relationship(back_populates="media")


class Tour(Base):
    __tablename__ = "tours"
    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    slug: Mapped[str] = mapped_column(String(64), unique=True)
    name: Mapped[str] = mapped_column(String(200))
    description: Mapped[str] = mapped_column(Text, default="")
    stops: Mapped[list[TourStop]] = relationship(
        back_populates="tour", cascade="all, delete-orphan", order_by="TourStop.position"
    )


class TourStop(Base):
    __tablename__ = "tour_stops"
    tour_id: Mapped[int] = mapped_column(ForeignKey("tours.id", ondelete="CASCADE"), primary_key=True)
    position: Mapped[int] = mapped_column(Integer, primary_key=True)
    exhibit_id: Mapped[int] = mapped_column(ForeignKey("exhibits.id", ondelete="CASCADE"))
    tour: Mapped[Tour] = relationship(back_populates="stops")
    exhibit: Mapped[Exhibit] = relationship()


class StaffUser(Base):
    __tablename__ = "staff_users"
    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    username: Mapped[str] = mapped_column(String(64), unique=True)
    password_hash: Mapped[str] = mapped_column(String(200))


class VisitorSession(Base):
    """A browser (web visitor, on-board screen or staff); the cookie holds the token, we its hash."""

    __tablename__ = "visitor_sessions"
    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    token_hash: Mapped[str] = mapped_column(String(64), unique=True)
    kind: Mapped[str] = mapped_column(String(16), default="web")
    created: Mapped[float] = mapped_column(Float)
    last_seen: Mapped[float] = mapped_column(Float)
    staff_user_id: Mapped[int | None] = mapped_column(ForeignKey("staff_users.id"), nullable=True)


class Booking(Base):
    """One control slot: who held which robot, from when to when, and why it ended."""

    __tablename__ = "control_bookings"
    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    robot_id: Mapped[int] = mapped_column(ForeignKey("robots.id"))
    session_id: Mapped[int] = mapped_column(ForeignKey("visitor_sessions.id"))
    started: Mapped[float] = mapped_column(Float)
    ended: Mapped[float | None] = mapped_column(Float, nullable=True)
    end_reason: Mapped[str] = mapped_column(String(32), default="")


class Visit(Base):
    """Visit statistics: an exhibit the robot was sent to, by whom (web, onboard, tour)."""

    __tablename__ = "visits"
    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    exhibit_id: Mapped[int] = mapped_column(ForeignKey("exhibits.id", ondelete="CASCADE"))
    robot_id: Mapped[int] = mapped_column(ForeignKey("robots.id"))
    source: Mapped[str] = mapped_column(String(16))
    at: Mapped[float] = mapped_column(Float)


class ChatMessage(Base):
    """A text message of one conversation: the visitor session in control of a robot (``session``)
    and the people on site; ``sender`` is ``visitor``, ``staff`` or ``onboard``."""

    __tablename__ = "chat_messages"
    __table_args__ = (Index("ix_chat_messages_robot", "robot_id", "id"),)
    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    robot_id: Mapped[int] = mapped_column(ForeignKey("robots.id"))
    session_id: Mapped[int] = mapped_column(ForeignKey("visitor_sessions.id"))
    sender: Mapped[str] = mapped_column(String(16))
    text: Mapped[str] = mapped_column(String(500))
    at: Mapped[float] = mapped_column(Float)


def default_url(site: str = "site") -> str:
    """``$DATABASE_URL``, else a SQLite file ``tourbot-SITE.db`` in the current folder."""
    return os.environ.get("DATABASE_URL") or f"sqlite:///tourbot-{site}.db"


def migrate(engine: Engine, revision: str = "head") -> None:
    """Bring the schema to ``revision`` with the shipped alembic migrations (data is kept)."""
    from alembic import command
    from alembic.config import Config

    config = Config()
    config.set_main_option("script_location", str(MIGRATIONS))
    with engine.begin() as connection:
        config.attributes["connection"] = connection
        command.upgrade(config, revision)


MIN_STAFF_PASSWORD = 8
_SAFE_SCHEMES = ("http://", "https://")


def check_link_url(url: str) -> None:
    """Refuse a picture or link URL that is not ``http(s)://...`` or a path on this site
    (``javascript:``, ``data:`` and protocol-relative ``//host`` links are never stored)."""
    stripped = url.strip()
    lowered = stripped.lower()
    on_site = stripped.startswith("/") and not stripped.startswith(("//", "/\\"))
    if not (lowered.startswith(_SAFE_SCHEMES) or on_site) or any(ord(c) < 32 for c in url):
        raise DatabaseError("a link must start with http://, https:// or / (a page of this site)")


def check_staff_password(password: str) -> None:
    """Refuse a staff password shorter than ``MIN_STAFF_PASSWORD`` characters."""
    if len(password) < MIN_STAFF_PASSWORD:
        raise DatabaseError(f"a staff password needs at least {MIN_STAFF_PASSWORD} characters")


def _hash_password(password: str, salt: bytes | None = None) -> str:
    salt = salt or secrets.token_bytes(16)
    digest = hashlib.scrypt(password.encode(), salt=salt, n=2**14, r=8, p=1)
    return f"scrypt${salt.hex()}${digest.hex()}"


def _check_password(password: str, stored: str) -> bool:
    try:
        _, salt, _digest = stored.split("$")
        expected = _hash_password(password, bytes.fromhex(salt))
    except ValueError:
        return False
    return hmac.compare_digest(expected, stored)


def token_hash(token: str) -> str:
    return hashlib.sha256(token.encode()).hexdigest()


@dataclass(frozen=True)
class ExhibitData:
    """An exhibit as pages and commands see it (plain data, JSON-ready)."""

    id: int
    slug: str
    name: str
    text: str
    summary: str
    x: float
    y: float
    theta: float
    pictures: tuple[tuple[str, str], ...] = ()
    links: tuple[tuple[str, str], ...] = ()

    def as_dict(self) -> dict[str, object]:
        return {
            "id": self.id,
            "slug": self.slug,
            "name": self.name,
            "text": self.text,
            "summary": self.summary,
            "x": self.x,
            "y": self.y,
            "theta": self.theta,
            "pictures": [{"url": u, "caption": c} for u, c in self.pictures],
            "links": [{"url": u, "caption": c} for u, c in self.links],
        }


@dataclass(frozen=True)
class TourData:
    id: int
    slug: str
    name: str
    description: str
    exhibits: tuple[str, ...]

    def as_dict(self) -> dict[str, object]:
        return {
            "id": self.id,
            "slug": self.slug,
            "name": self.name,
            "description": self.description,
            "exhibits": list(self.exhibits),
        }


@dataclass(frozen=True)
class MessageData:
    """A chat message as the pages get it (the conversation's session id is the server's only)."""

    id: int
    robot_id: int
    session: int
    sender: str
    text: str
    at: float

    def as_dict(self) -> dict[str, object]:
        return {"id": self.id, "sender": self.sender, "text": self.text, "at": round(self.at, 3)}


CHAT_SENDERS = ("visitor", "staff", "onboard")
MAX_CHAT_CHARS = 500


def _exhibit_data(e: Exhibit) -> ExhibitData:
    return ExhibitData(
        e.id,
        e.slug,
        e.name,
        e.text,
        e.summary,
        e.x,
        e.y,
        e.theta,
        tuple((m.url, m.caption) for m in e.media if m.kind == "picture"),
        tuple((m.url, m.caption) for m in e.media if m.kind == "link"),
    )


class Database:
    """The site database: content (exhibits, tours), sessions, bookings, statistics, staff."""

    busy_timeout = 30.0  # SQLite: a writer waits this long (s) for another's lock, not failing

    def __init__(self, url: str) -> None:
        self.url = url
        try:
            sqlite = sqlite_file(url) is not None
            connect_args = {"timeout": self.busy_timeout} if sqlite else {}
            self.engine = create_engine(url, future=True, pool_pre_ping=True, connect_args=connect_args)
        except Exception as exc:  # a malformed URL, an unknown driver
            raise DatabaseError(f"cannot open the database {url!r}: {exc}") from exc
        if sqlite:
            event.listen(self.engine, "connect", _sqlite_pragmas)
        self._sessions = sessionmaker(self.engine, expire_on_commit=False)

    @contextmanager
    def session(self) -> Iterator[Session]:
        with self._sessions.begin() as s:
            yield s

    # --- content -------------------------------------------------------------------------
    def exhibits(self) -> list[ExhibitData]:
        with self.session() as s:
            return [_exhibit_data(e) for e in s.scalars(select(Exhibit).order_by(Exhibit.id))]

    def exhibit(self, key: int | str) -> ExhibitData:
        with self.session() as s:
            found = self._find_exhibit(s, key)
            return _exhibit_data(found)

    @staticmethod
    def _find_exhibit(s: Session, key: int | str) -> Exhibit:
        column = Exhibit.id if isinstance(key, int) else Exhibit.slug
        found = s.scalars(select(Exhibit).where(column == key)).first()
        if found is None:
            raise DatabaseError(f"no exhibit {key!r}")
        return found

    def save_exhibit(
        self,
        slug: str,
        name: str,
        *,
        x: float,
        y: float,
        theta: float = 0.0,
        text: str = "",
        summary: str = "",
        pictures: Sequence[tuple[str, str]] = (),
        links: Sequence[tuple[str, str]] = (),
    ) -> ExhibitData:
        """Add the exhibit ``slug``, or replace its content and place if it exists."""
        if not slug or len(slug) > 64:
            raise DatabaseError(f"exhibit slug must have 1 to 64 characters, got {slug!r}")
        for url, _ in [*pictures, *links]:
            check_link_url(url)
        with self.session() as s:
            found = s.scalars(select(Exhibit).where(Exhibit.slug == slug)).first()
            if found is None:
                found = Exhibit(slug=slug)
                s.add(found)
            found.name, found.text, found.summary = name, text, summary
            found.x, found.y, found.theta = float(x), float(y), float(theta)
            found.media = [
                Media(kind=kind, url=url, caption=caption, position=i)
                for i, (kind, (url, caption)) in enumerate(
                    [("picture", p) for p in pictures] + [("link", link) for link in links]
                )
            ]
            s.flush()
            return _exhibit_data(found)

    def place_exhibit(self, key: int | str, x: float, y: float, theta: float | None = None) -> ExhibitData:
        with self.session() as s:
            found = self._find_exhibit(s, key)
            found.x, found.y = float(x), float(y)
            if theta is not None:
                found.theta = float(theta)
            s.flush()
            return _exhibit_data(found)

    def delete_exhibit(self, key: int | str) -> None:
        with self.session() as s:
            found = self._find_exhibit(s, key)
            s.execute(delete(TourStop).where(TourStop.exhibit_id == found.id))
            s.execute(delete(Visit).where(Visit.exhibit_id == found.id))
            s.delete(found)

    def tours(self) -> list[TourData]:
        with self.session() as s:
            return [
                TourData(t.id, t.slug, t.name, t.description, tuple(st.exhibit.slug for st in t.stops))
                for t in s.scalars(select(Tour).order_by(Tour.id))
            ]

    def tour(self, key: int | str) -> TourData:
        for t in self.tours():
            if key in (t.id, t.slug):
                return t
        raise DatabaseError(f"no tour {key!r}")

    def save_tour(self, slug: str, name: str, exhibits: Sequence[str], description: str = "") -> TourData:
        """Add or replace the tour ``slug``: its exhibits, by slug, in visiting order."""
        if not slug or len(slug) > 64:
            raise DatabaseError(f"tour slug must have 1 to 64 characters, got {slug!r}")
        with self.session() as s:
            ids = [self._find_exhibit(s, e).id for e in exhibits]
            found = s.scalars(select(Tour).where(Tour.slug == slug)).first()
            if found is None:
                found = Tour(slug=slug)
                s.add(found)
            found.name, found.description = name, description
            found.stops = []
            s.flush()
            found.stops = [TourStop(position=i, exhibit_id=e) for i, e in enumerate(ids)]
        return self.tour(slug)

    def delete_tour(self, key: int | str) -> None:
        tour = self.tour(key)
        with self.session() as s:
            s.execute(delete(TourStop).where(TourStop.tour_id == tour.id))
            s.execute(delete(Tour).where(Tour.id == tour.id))

    # --- robots, sessions, bookings, statistics ------------------------------------------
    def robot_id(self, name: str, site: str = "") -> int:
        with self.session() as s:
            found = s.scalars(select(Robot).where(Robot.name == name)).first()
            if found is None:
                found = Robot(name=name, site=site)
                s.add(found)
                s.flush()
            return found.id

    def new_session(self, kind: str = "web", staff_user_id: int | None = None) -> tuple[str, int]:
        """A fresh session: the secret token for the cookie, and the session's id."""
        token = secrets.token_urlsafe(32)
        now = time.time()
        with self.session() as s:
            row = VisitorSession(
                token_hash=token_hash(token),
                kind=kind,
                created=now,
                last_seen=now,
                staff_user_id=staff_user_id,
            )
            s.add(row)
            s.flush()
            return token, row.id

    def session_for(self, token: str, max_idle: float = float("inf")) -> tuple[int, str, int | None] | None:
        """``(id, kind, staff user)`` of the session holding ``token``, or None; a session unused
        for more than ``max_idle`` seconds is ended (None)."""
        now = time.time()
        with self.session() as s:
            row = s.scalars(
                select(VisitorSession).where(VisitorSession.token_hash == token_hash(token))
            ).first()
            if row is None:
                return None
            if now - row.last_seen > max_idle:
                row.token_hash = f"ended-{row.id}"
                return None
            row.last_seen = now
            return row.id, row.kind, row.staff_user_id

    def touch_session(self, token: str, now: float) -> None:
        """Record that the session holding ``token`` was used at ``now``."""
        with self.session() as s:
            row = self._session_row(s, token)
            if row is not None:
                row.last_seen = now

    @staticmethod
    def _session_row(s: Session, token: str) -> VisitorSession | None:
        return s.scalars(select(VisitorSession).where(VisitorSession.token_hash == token_hash(token))).first()

    def end_session(self, token: str) -> None:
        """Invalidate the token; the row stays, since bookings keep referring to it."""
        with self.session() as s:
            row = s.scalars(
                select(VisitorSession).where(VisitorSession.token_hash == token_hash(token))
            ).first()
            if row is not None:
                row.token_hash = f"ended-{row.id}"

    def booking_started(self, robot_id: int, session_id: int, now: float) -> int:
        with self.session() as s:
            row = Booking(robot_id=robot_id, session_id=session_id, started=now)
            s.add(row)
            s.flush()
            return row.id

    def booking_ended(self, booking_id: int, now: float, reason: str) -> None:
        with self.session() as s:
            row = s.get(Booking, booking_id)
            if row is not None:
                row.ended, row.end_reason = now, reason

    def bookings(self) -> list[tuple[int, int, float, float | None, str]]:
        with self.session() as s:
            return [
                (b.robot_id, b.session_id, b.started, b.ended, b.end_reason)
                for b in s.scalars(select(Booking).order_by(Booking.id))
            ]

    def record_visit(self, exhibit: int | str, robot_id: int, source: str, now: float) -> None:
        with self.session() as s:
            s.add(
                Visit(exhibit_id=self._find_exhibit(s, exhibit).id, robot_id=robot_id, source=source, at=now)
            )

    def visit_counts(self) -> dict[str, int]:
        """How often each exhibit was visited (statistics for the admin page)."""
        with self.session() as s:
            rows = s.execute(
                select(Exhibit.slug, func.count(Visit.id)).join(Visit, isouter=True).group_by(Exhibit.slug)
            )
            return {slug: int(n) for slug, n in rows}

    # --- the text channel ----------------------------------------------------------------
    def add_message(self, robot_id: int, session_id: int, sender: str, text: str, now: float) -> MessageData:
        """Store a message of the conversation with visitor session ``session_id`` on a robot."""
        if sender not in CHAT_SENDERS:
            raise DatabaseError(f"a message's sender is one of {', '.join(CHAT_SENDERS)}")
        if not text or len(text) > MAX_CHAT_CHARS:
            raise DatabaseError(f"a message has 1 to {MAX_CHAT_CHARS} characters")
        with self.session() as s:
            row = ChatMessage(robot_id=robot_id, session_id=session_id, sender=sender, text=text, at=now)
            s.add(row)
            s.flush()
            return MessageData(row.id, robot_id, session_id, sender, text, now)

    def messages(self, robot_id: int, limit: int = 50, session_id: int | None = None) -> list[MessageData]:
        """The latest ``limit`` messages on a robot (of one conversation if ``session_id``), oldest first."""
        query = select(ChatMessage).where(ChatMessage.robot_id == robot_id)
        if session_id is not None:
            query = query.where(ChatMessage.session_id == session_id)
        with self.session() as s:
            rows = s.scalars(query.order_by(ChatMessage.id.desc()).limit(limit)).all()
            return [
                MessageData(r.id, r.robot_id, r.session_id, r.sender, r.text, r.at) for r in reversed(rows)
            ]

    # --- staff ---------------------------------------------------------------------------
    def set_staff(self, username: str, password: str) -> None:
        check_staff_password(password)
        with self.session() as s:
            found = s.scalars(select(StaffUser).where(StaffUser.username == username)).first()
            if found is None:
                found = StaffUser(username=username)
                s.add(found)
            found.password_hash = _hash_password(password)

    def has_staff(self) -> bool:
        with self.session() as s:
            return s.scalars(select(StaffUser.id)).first() is not None

    def check_staff(self, username: str, password: str) -> int | None:
        """The staff user's id when the password is right, else None."""
        with self.session() as s:
            found = s.scalars(select(StaffUser).where(StaffUser.username == username)).first()
            if found is None:
                _hash_password(password)  # same work either way: no timing hint that the name exists
                return None
            return found.id if _check_password(password, found.password_hash) else None


def open_database(url: str | None = None, *, site: str = "site") -> Database:
    """Open (creating or upgrading its schema) the site database at ``url`` or :func:`default_url`."""
    url = url or default_url(site)
    _create_sqlite_folder(url)
    db = Database(url)
    try:
        migrate(db.engine)
    except Exception as exc:
        if isinstance(exc, TourbotError):
            raise
        # one line: the driver's own message, without SQLAlchemy's SQL echo and background link
        reason = str(getattr(exc, "orig", None) or exc).strip().splitlines()[0]
        raise DatabaseError(f"cannot prepare the database {db.url!r}: {reason}") from exc
    return db


def _sqlite_pragmas(connection: object, _: object) -> None:
    """Each SQLite connection: write-ahead log (readers never block the writer), a busy timeout
    (a writer waits for the lock instead of failing with "database is locked")."""
    cursor = connection.cursor()  # type: ignore[attr-defined]
    cursor.execute("PRAGMA journal_mode=WAL")
    cursor.execute(f"PRAGMA busy_timeout={int(Database.busy_timeout * 1000)}")
    cursor.execute("PRAGMA synchronous=NORMAL")
    cursor.close()


def sqlite_file(url: str) -> Path | None:
    """The file of a SQLite database URL (None for other databases, in-memory ones and bad URLs)."""
    from sqlalchemy.engine import make_url
    from sqlalchemy.exc import ArgumentError

    try:
        parsed = make_url(url)
    except ArgumentError:
        return None  # Database() reports the malformed URL
    if parsed.get_backend_name() == "sqlite" and parsed.database not in (None, "", ":memory:"):
        return Path(parsed.database)
    return None


def _create_sqlite_folder(url: str) -> None:
    """Create the folder of a SQLite database file, as for any output path (other URLs untouched)."""
    path = sqlite_file(url)
    if path is not None:
        try:
            path.parent.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise DatabaseError(
                f"cannot create the folder of the database {url!r}: {exc.strerror or exc}"
            ) from exc
