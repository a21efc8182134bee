"""The tele-presence server (Burgard et al., section 6): ``create_app`` builds it.

* ``/`` the remote visitor page: tours and exhibits, exhibit information, status messages, the
  live 2D floor plan and the 3D view, control slots;
* ``/onboard`` the robot's own touch screen (reached from the robot itself, or by staff);
* ``/admin`` staff authoring: exhibits, tours, placing them on the map, statistics, staff stop;
* ``/ws/{robot}`` the live stream (binary, :mod:`tourbot.web.stream`) and the commands (JSON,
  :mod:`tourbot.web.guard`), one connection per page.

Several robots in one museum (WebFAIR): each robot has its own control queue, and a visitor chooses
the robot on the page (``/api/robots`` says who is driving each and how many wait). The visitor in
control may ask for a high-resolution picture of the robot's camera (``/api/robots/{robot}/photo``),
ask the robot to move around an exhibit, and write to the people on site: the staff answer from the
staff page, the robot's own screen shows the messages and answers too (the text channel, stored in
the site database).

A session is a random token in an HttpOnly cookie; the server keeps only its hash. Only the slot
holder's commands move a robot, checked here on the server, never in the page.
"""

from __future__ import annotations

import asyncio
import base64
import hashlib
import hmac
import io
import json
import math
import os
import re
import time
from collections.abc import AsyncIterator, Mapping
from contextlib import asynccontextmanager, suppress
from dataclasses import dataclass, field
from pathlib import Path
from typing import Annotated, Any

import numpy as np
from fastapi import (
    Depends,
    FastAPI,
    HTTPException,
    Query,
    Request,
    Response,
    WebSocket,
    WebSocketDisconnect,
)
from fastapi.exceptions import RequestValidationError
from fastapi.responses import FileResponse, HTMLResponse, JSONResponse, RedirectResponse
from fastapi.staticfiles import StaticFiles
from pydantic import AfterValidator, BaseModel, ConfigDict, Field
from starlette.websockets import WebSocketState

from tourbot.errors import TourbotError
from tourbot.maps.grid import OccupancyGrid
from tourbot.web.db import Database, DatabaseError, check_link_url
from tourbot.web.face import FaceConfig
from tourbot.web.guard import (
    MAX_CHAT_TEXT,
    Around,
    Book,
    Chat,
    CommandError,
    GoTo,
    GoToExhibit,
    GuardConfig,
    Leave,
    Ping,
    Say,
    StartTour,
    Stop,
    TokenBucket,
    origin_allowed,
    parse_command,
)
from tourbot.web.hub import RobotHub, StreamViewer, robots_summary
from tourbot.web.link import RobotLink
from tourbot.web.middleware import BodyLimit, SameOrigin
from tourbot.web.phrases import EXHIBIT, IDLE, TOUR, PhraseBook
from tourbot.web.slots import SlotConfig
from tourbot.web.speech import Speaker, SpeechConfig
from tourbot.web.stream import FRAME_KEY, StreamConfig

__all__ = ["WebConfig", "create_app", "find_node_modules", "known_bounds", "pooled", "wall_boxes"]

STATIC = Path(__file__).with_name("static")
COOKIE = "tourbot_session"
_SPEECH_NAME = re.compile(r"^[0-9a-f]{24}\.wav$")
_IMPORTMAP = re.compile(r'<script type="importmap">(.*?)</script>', re.DOTALL)


def find_node_modules(start: Path | None = None) -> Path | None:
    """``node_modules`` holding three.js: ``$TOURBOT_NODE_MODULES``, else the checkout's, searched
    upwards from ``start`` (default the current folder) and from this package."""
    env = os.environ.get("TOURBOT_NODE_MODULES")
    if env:
        return Path(env) if (Path(env) / "three" / "build" / "three.module.js").is_file() else None
    for base in (start or Path.cwd(), Path(__file__).resolve()):
        for parent in [base, *base.parents]:
            candidate = parent / "node_modules"
            if (candidate / "three" / "build" / "three.module.js").is_file():
                return candidate
    return None


@dataclass(frozen=True)
class WebConfig:
    """Everything the server can be told, with the paper's values where it gives them.

    ``onboard_token``: the secret that pairs the robot's own screen (``/onboard/pair?token=...``,
    once per device; the screen is never recognised by its address). ``secure_cookies``: the
    session cookie only over TLS (set when serving HTTPS). ``session_idle``: a session unused this
    long (s) is ended on the server. ``sessions_per_minute``: new sessions one address may start
    (sustained; twice that at once). ``max_body_bytes``: the largest request body of any route.
    """

    site_name: str = "the museum"
    slots: SlotConfig = field(default_factory=SlotConfig)
    stream: StreamConfig = field(default_factory=StreamConfig)
    guard: GuardConfig = field(default_factory=GuardConfig)
    face: FaceConfig = field(default_factory=FaceConfig)
    speech: SpeechConfig = field(default_factory=SpeechConfig)
    speech_dir: Path = Path("tourbot-speech")
    node_modules: Path | None = None
    allowed_origins: tuple[str, ...] = ()
    onboard_token: str | None = None
    secure_cookies: bool = False
    session_idle: float = 6 * 3600.0
    sessions_per_minute: float = 10.0
    max_body_bytes: int = 64 * 1024
    login_attempts_per_minute: int = 6
    drive_robots: bool = True
    photo_interval: float = 5.0  # s between two high-resolution pictures of one robot's camera


@dataclass
class _Client:
    session: int
    kind: str
    staff: bool
    seen: float = field(default_factory=time.time)  # last use (the server ends idle sessions)
    stored: float = field(default_factory=time.time)  # last use written to the database
    chat: TokenBucket | None = None  # the text channel's rate limit of this session


class _Login(BaseModel):
    model_config = ConfigDict(extra="forbid")
    username: Annotated[str, Field(min_length=1, max_length=64)]
    password: Annotated[str, Field(min_length=1, max_length=200)]


def _safe_url(url: str) -> str:
    try:
        check_link_url(url)
    except DatabaseError as exc:
        raise ValueError(str(exc)) from None
    return url


class _Link(BaseModel):
    model_config = ConfigDict(extra="forbid")
    url: Annotated[str, Field(min_length=1, max_length=1000), AfterValidator(_safe_url)]
    caption: Annotated[str, Field(max_length=400)] = ""


class _ExhibitIn(BaseModel):
    model_config = ConfigDict(extra="forbid")
    slug: Annotated[str, Field(min_length=1, max_length=64, pattern=r"^[a-z0-9][a-z0-9_-]*$")]
    name: Annotated[str, Field(min_length=1, max_length=200)]
    text: Annotated[str, Field(max_length=20000)] = ""
    summary: Annotated[str, Field(max_length=400)] = ""
    x: Annotated[float, Field(ge=-1e4, le=1e4)]
    y: Annotated[float, Field(ge=-1e4, le=1e4)]
    theta: Annotated[float, Field(ge=-10, le=10)] = 0.0
    pictures: Annotated[list[_Link], Field(max_length=20)] = []
    links: Annotated[list[_Link], Field(max_length=20)] = []


class _Place(BaseModel):
    model_config = ConfigDict(extra="forbid")
    x: Annotated[float, Field(ge=-1e4, le=1e4)]
    y: Annotated[float, Field(ge=-1e4, le=1e4)]
    theta: Annotated[float, Field(ge=-10, le=10)] | None = None


class _ChatIn(BaseModel):
    model_config = ConfigDict(extra="forbid")
    text: Annotated[str, Field(min_length=1, max_length=MAX_CHAT_TEXT)]


class _TourIn(BaseModel):
    model_config = ConfigDict(extra="forbid")
    slug: Annotated[str, Field(min_length=1, max_length=64, pattern=r"^[a-z0-9][a-z0-9_-]*$")]
    name: Annotated[str, Field(min_length=1, max_length=200)]
    description: Annotated[str, Field(max_length=4000)] = ""
    exhibits: Annotated[list[str], Field(max_length=100)]


def _staff(request: Request) -> _Client:
    """The logged-in staff member making ``request``; 401 otherwise (a FastAPI dependency)."""
    client = request.app.state.lookup(request.cookies.get(COOKIE))
    if client is None or not client.staff:
        raise HTTPException(401, "staff login required")
    return client


Staff = Annotated[_Client, Depends(_staff)]


def _policy(html: str) -> str:
    """Content security policy: our own scripts only, plus the page's inline import map by hash."""
    hashes = [
        "'sha256-" + base64.b64encode(hashlib.sha256(m.encode()).digest()).decode() + "'"
        for m in _IMPORTMAP.findall(html)
    ]
    return (
        "default-src 'self'; img-src 'self' data: blob: https:; media-src 'self' blob:; "
        f"connect-src 'self'; style-src 'self' 'unsafe-inline'; script-src 'self' {' '.join(hashes)}"
    ).strip()


def _map_png(grid: OccupancyGrid) -> bytes:
    """The floor plan, north up: free white, occupied black, unknown grey."""
    from PIL import Image

    prob = grid.prob
    shade = np.where(prob < 0, 205, 255 - np.clip(prob, 0, 1) * 255).astype(np.uint8)
    buffer = io.BytesIO()
    Image.fromarray(shade[::-1]).save(buffer, format="PNG", optimize=True)
    return buffer.getvalue()


def known_bounds(grid: OccupancyGrid, margin: int = 4) -> list[int]:
    """The part of the floor-plan image that is mapped, ``[u0, v0, u1, v1]`` in image pixels (u
    right, v down, north up as :func:`_map_png` draws it; ends exclusive), ``margin`` cells wider:
    the pages draw this part only, so the building fills the canvas, not the unknown around it."""
    known = grid.prob[::-1] >= 0
    rows, cols = known.shape
    if not known.any():
        return [0, 0, cols, rows]
    v = np.flatnonzero(known.any(axis=1))
    u = np.flatnonzero(known.any(axis=0))
    return [
        max(0, int(u[0]) - margin),
        max(0, int(v[0]) - margin),
        min(cols, int(u[-1]) + 1 + margin),
        min(rows, int(v[-1]) + 1 + margin),
    ]


def pooled(occupied: np.ndarray, factor: int) -> np.ndarray:
    """Occupancy at ``factor`` times coarser cells: a coarse cell is occupied when any of its fine
    cells is (the last row and column padded free)."""
    if factor == 1:
        return occupied
    rows, cols = occupied.shape
    padded = np.zeros((-(-rows // factor) * factor, -(-cols // factor) * factor), dtype=bool)
    padded[:rows, :cols] = occupied
    blocks = padded.reshape(padded.shape[0] // factor, factor, padded.shape[1] // factor, factor)
    return np.asarray(blocks.any(axis=(1, 3)), dtype=bool)


def wall_boxes(occupied: np.ndarray) -> list[list[int]]:
    """Occupied cells merged into boxes ``[col0, row0, col1, row1]`` (ends exclusive): each row's
    runs of occupied cells, and a run that repeats exactly in the next row grows its box instead of
    starting a new one. A wall one cell thick is one long box, whichever way it runs; every
    occupied cell is in exactly one box."""
    boxes: list[list[int]] = []
    open_boxes: dict[tuple[int, int], list[int]] = {}  # (col0, col1) -> the box ending at this row
    for row in range(occupied.shape[0]):
        line = np.concatenate([[False], occupied[row], [False]]).astype(np.int8)
        edges = np.flatnonzero(np.diff(line))
        runs = {(int(a), int(b)) for a, b in zip(edges[::2], edges[1::2], strict=True)}
        for key in list(open_boxes):
            if key not in runs:
                boxes.append(open_boxes.pop(key))
        for a, b in sorted(runs):
            box = open_boxes.get((a, b))
            if box is None:
                open_boxes[(a, b)] = [a, row, b, row + 1]
            else:
                box[3] = row + 1
    boxes.extend(open_boxes.values())
    return sorted(boxes, key=lambda box: (box[1], box[0]))


def create_app(
    robots: Mapping[str, RobotLink],
    db: Database,
    grid: OccupancyGrid | None = None,
    config: WebConfig | None = None,
) -> FastAPI:
    """The server for ``robots`` (name -> link) with the site content of ``db`` on map ``grid``."""
    cfg = config or WebConfig()
    if not robots:
        raise DatabaseError("the server needs at least one robot")
    speaker = Speaker(cfg.speech_dir, cfg.speech)

    def speak(text: str) -> str | None:
        path = speaker.say(text)
        return None if path is None else path.name

    hubs = {
        name: RobotHub(
            name,
            link,
            db,
            db.robot_id(name, cfg.site_name),
            cfg.slots,
            cfg.face,
            cfg.stream.rate_hz,
            speak,
            cfg.drive_robots,
            cfg.stream,
        )
        for name, link in robots.items()
    }
    map_png = _map_png(grid) if grid is not None else None
    map_crop = known_bounds(grid) if grid is not None else None
    # the 3D walls at about 10 cm: a scanned map's ragged wall edges merge into few boxes
    wall_cell = 1 if grid is None else max(1, round(0.1 / grid.resolution))
    walls = wall_boxes(pooled(grid.occupied(), wall_cell)) if grid is not None else []
    buckets: dict[int, TokenBucket] = {}
    login_buckets: dict[str, TokenBucket] = {}
    sessions: dict[str, _Client] = {}

    @asynccontextmanager
    async def lifespan(_: FastAPI) -> AsyncIterator[None]:
        for hub in hubs.values():
            await hub.start()
        yield
        for hub in hubs.values():
            await hub.close()

    app = FastAPI(
        title="tourbot", lifespan=lifespan, docs_url=None, redoc_url=None, openapi_url="/api/openapi.json"
    )
    app.state.hubs = hubs
    for hub in hubs.values():
        hub.museum = list(hubs.values())
    app.state.db = db
    app.state.config = cfg
    # Outermost first: the body limit, then cross-site refusal, both before any route runs.
    app.add_middleware(SameOrigin, allowed=cfg.allowed_origins)
    app.add_middleware(BodyLimit, max_bytes=cfg.max_body_bytes)

    @app.exception_handler(RequestValidationError)
    async def invalid(_: Request, exc: RequestValidationError) -> JSONResponse:
        """Where the request is wrong and why, never the request itself (no ``input`` echoed)."""
        errors = []
        for e in exc.errors()[:10]:
            loc = [str(p) for p in e.get("loc", ())][:4]
            if e.get("type") == "extra_forbidden":  # the last part is the client's own field name
                loc = [*loc[:-1], "(unknown field)"]
            errors.append({"loc": loc, "msg": str(e.get("msg", ""))[:200]})
        return JSONResponse({"detail": errors}, status_code=422)

    # --- sessions ------------------------------------------------------------------------
    session_buckets: dict[str, TokenBucket] = {}

    def lookup(token: str | None) -> _Client | None:
        if not token or len(token) > 100:
            return None
        now = time.time()
        client = sessions.get(token)
        if client is None:
            found = db.session_for(token, max_idle=cfg.session_idle)
            if found is None:
                return None
            client = sessions[token] = _Client(found[0], found[1], found[2] is not None)
        if now - client.seen > cfg.session_idle:
            sessions.pop(token, None)
            db.end_session(token)
            return None
        client.seen = now
        if now - client.stored > 60.0:  # the database learns of use once a minute at most
            client.stored = now
            db.touch_session(token, now)
        return client

    app.state.lookup = lookup

    def set_cookie(request: Request, response: Response, token: str) -> None:
        secure = cfg.secure_cookies or request.url.scheme == "https"
        response.set_cookie(COOKIE, token, httponly=True, samesite="strict", path="/", secure=secure)

    def address(request: Request) -> str:
        return request.client.host if request.client else "?"

    def ensure_session(request: Request, response: Response, kind: str = "web") -> _Client:
        client = lookup(request.cookies.get(COOKIE))
        if client is None:
            rate = cfg.sessions_per_minute / 60.0
            bucket = session_buckets.setdefault(
                address(request), TokenBucket(rate, max(1, int(2 * cfg.sessions_per_minute)))
            )
            if not bucket.allow(time.monotonic()):
                raise HTTPException(429, "too many new sessions from this address; wait a minute")
            token, sid = db.new_session(kind)
            client = _Client(sid, kind, False)
            sessions[token] = client
            set_cookie(request, response, token)
        return client

    def is_onboard(client: _Client | None) -> bool:
        return client is not None and (client.kind == "onboard" or client.staff)

    def hub_for(name: str) -> RobotHub:
        if name not in hubs:
            raise HTTPException(404, "no such robot")
        return hubs[name]

    # --- pages ---------------------------------------------------------------------------
    def page(name: str, request: Request, kind: str = "web") -> HTMLResponse:
        html = (STATIC / name).read_text()
        response = HTMLResponse(html)
        ensure_session(request, response, kind)
        response.headers["Content-Security-Policy"] = _policy(html)
        response.headers["X-Content-Type-Options"] = "nosniff"
        response.headers["Referrer-Policy"] = "same-origin"
        return response

    @app.get("/", response_class=HTMLResponse)
    def visitor_page(request: Request) -> HTMLResponse:
        return page("visitor.html", request)

    @app.get("/onboard", response_class=HTMLResponse)
    def onboard_page(request: Request) -> HTMLResponse:
        if not is_onboard(lookup(request.cookies.get(COOKIE))):
            raise HTTPException(403, "the on-board screen is served to the paired robot screen or to staff")
        return page("onboard.html", request, "onboard")

    @app.get("/onboard/pair")
    def onboard_pair(request: Request, token: Annotated[str, Query(max_length=200)] = "") -> Response:
        """Pair the robot's own screen: the right token gives this browser an on-board session."""
        bucket = login_buckets.setdefault(
            address(request), TokenBucket(cfg.login_attempts_per_minute / 60.0, 3)
        )
        if not bucket.allow(time.monotonic()):
            raise HTTPException(429, "too many attempts; wait a minute")
        expected = cfg.onboard_token
        if not expected or not hmac.compare_digest(token.encode(), expected.encode()):
            raise HTTPException(403, "wrong pairing token")
        session, sid = db.new_session("onboard")
        sessions[session] = _Client(sid, "onboard", False)
        response = RedirectResponse("/onboard", status_code=303)
        set_cookie(request, response, session)
        return response

    @app.get("/admin", response_class=HTMLResponse)
    def admin_page(request: Request) -> HTMLResponse:
        return page("admin.html", request)

    app.mount("/static", StaticFiles(directory=STATIC), name="static")
    modules = cfg.node_modules or find_node_modules()
    if modules is not None:
        app.mount("/vendor/three", StaticFiles(directory=modules / "three"), name="three")

    @app.get("/favicon.ico")
    def favicon() -> Response:
        return Response(status_code=204)

    @app.get("/speech/{name}")
    def speech_file(name: str) -> FileResponse:
        if not _SPEECH_NAME.match(name) or not (cfg.speech_dir / name).is_file():
            raise HTTPException(404, "no such speech file")
        return FileResponse(cfg.speech_dir / name, media_type="audio/wav")

    # --- site content --------------------------------------------------------------------
    @app.get("/api/session")
    def api_session(request: Request, response: Response) -> dict[str, Any]:
        client = ensure_session(request, response)
        return {"session": client.session, "staff": client.staff}

    @app.get("/api/site")
    def api_site() -> dict[str, Any]:
        return {
            "name": cfg.site_name,
            "robots": list(hubs),
            "exhibits": [e.as_dict() for e in db.exhibits()],
            "tours": [t.as_dict() for t in db.tours()],
            "slot_length": cfg.slots.slot_length,
            "stream": {
                "rate_hz": cfg.stream.rate_hz,
                "position_quantum": cfg.stream.position_quantum,
                "velocity_quantum": cfg.stream.velocity_quantum,
                "turn_quantum": cfg.stream.turn_quantum,
                "time_quantum": cfg.stream.time_quantum,
                "horizon": cfg.stream.horizon,
            },
            "map": None
            if grid is None
            else {
                "resolution": grid.resolution,
                "origin": list(grid.origin),
                "rows": grid.shape[0],
                "cols": grid.shape[1],
                "crop": map_crop,
            },
            "three": modules is not None,
        }

    @app.get("/api/robots")
    async def api_robots() -> dict[str, Any]:
        """Each robot's control queue as a visitor choosing a robot sees it (no one's identity;
        the slots as the hubs last brought them up to date, five times a second). The pages get
        the same list over their WebSocket, on change (a ``robots`` message)."""
        robots = robots_summary(list(hubs.values()))
        for item, hub in zip(robots, hubs.values(), strict=True):
            item["state"] = hub.nav_status.get("state", "idle")
        return {"robots": robots}

    @app.post(
        "/api/robots/{name}/photo",
        response_class=Response,
        responses={200: {"content": {"image/jpeg": {}}, "description": "the picture"}},
    )
    async def robot_photo(request: Request, name: str) -> Response:
        """A high-resolution JPEG of the robot's camera, for the visitor in control only, at most
        one per ``photo_interval`` seconds and robot (rendering one takes the robot a moment)."""
        client = await asyncio.to_thread(lookup, request.cookies.get(COOKIE))
        hub = hub_for(name)
        now = time.time()
        if client is None or hub.arbiter.holder != client.session:
            raise HTTPException(403, "only the visitor in control of the robot may take pictures")
        wait = hub.photo_at + cfg.photo_interval - now
        if wait > 0:
            raise HTTPException(
                429,
                "one picture at a time: wait a few seconds",
                headers={"Retry-After": str(math.ceil(wait))},
            )
        hub.photo_at = now
        try:
            jpeg = await hub.command(lambda link: link.photo())
        except TourbotError:
            raise HTTPException(503, "the robot's camera gave no picture") from None
        return Response(jpeg, media_type="image/jpeg", headers={"Cache-Control": "no-store"})

    @app.get("/api/exhibits/{slug}")
    def api_exhibit(slug: str) -> dict[str, object]:
        try:
            return db.exhibit(slug).as_dict()
        except DatabaseError:
            raise HTTPException(404, "no such exhibit") from None

    @app.get("/api/map.png")
    def api_map_png() -> Response:
        if map_png is None:
            raise HTTPException(404, "this site has no map")
        return Response(map_png, media_type="image/png", headers={"Cache-Control": "max-age=3600"})

    @app.get("/api/walls")
    def api_walls() -> dict[str, Any]:
        """The 3D view's walls: the map's occupied cells as merged boxes (:func:`wall_boxes`)."""
        return {"boxes": walls, "cell": wall_cell}

    # --- staff ---------------------------------------------------------------------------
    @app.post("/api/login")
    def api_login(request: Request, body: _Login) -> JSONResponse:
        bucket = login_buckets.setdefault(
            address(request), TokenBucket(cfg.login_attempts_per_minute / 60.0, 3)
        )
        if not bucket.allow(time.monotonic()):
            raise HTTPException(429, "too many login attempts; wait a minute")
        user = db.check_staff(body.username, body.password)
        if user is None:
            raise HTTPException(401, "wrong user name or password")
        token, sid = db.new_session("staff", user)
        sessions[token] = _Client(sid, "staff", True)
        response = JSONResponse({"ok": True, "user": body.username})
        set_cookie(request, response, token)
        return response

    @app.post("/api/logout")
    def api_logout(request: Request) -> JSONResponse:
        token = request.cookies.get(COOKIE)
        if token:
            sessions.pop(token, None)
            db.end_session(token)
        response = JSONResponse({"ok": True})
        response.delete_cookie(COOKIE, path="/")
        return response

    @app.post("/api/admin/exhibits")
    def admin_save_exhibit(_: Staff, body: _ExhibitIn) -> dict[str, object]:
        saved = db.save_exhibit(
            body.slug,
            body.name,
            x=body.x,
            y=body.y,
            theta=body.theta,
            text=body.text,
            summary=body.summary,
            pictures=[(p.url, p.caption) for p in body.pictures],
            links=[(p.url, p.caption) for p in body.links],
        )
        return saved.as_dict()

    @app.post("/api/admin/exhibits/{slug}/place")
    def admin_place_exhibit(_: Staff, slug: str, body: _Place) -> dict[str, object]:
        try:
            return db.place_exhibit(slug, body.x, body.y, body.theta).as_dict()
        except DatabaseError:
            raise HTTPException(404, "no such exhibit") from None

    @app.delete("/api/admin/exhibits/{slug}")
    def admin_delete_exhibit(_: Staff, slug: str) -> dict[str, bool]:
        try:
            db.delete_exhibit(slug)
        except DatabaseError:
            raise HTTPException(404, "no such exhibit") from None
        return {"ok": True}

    @app.post("/api/admin/tours")
    def admin_save_tour(_: Staff, body: _TourIn) -> dict[str, object]:
        try:
            return db.save_tour(body.slug, body.name, body.exhibits, body.description).as_dict()
        except DatabaseError:
            raise HTTPException(422, "a tour's exhibits must all exist") from None

    @app.delete("/api/admin/tours/{slug}")
    def admin_delete_tour(_: Staff, slug: str) -> dict[str, bool]:
        try:
            db.delete_tour(slug)
        except DatabaseError:
            raise HTTPException(404, "no such tour") from None
        return {"ok": True}

    @app.get("/api/admin/stats")
    def admin_stats(_: Staff) -> dict[str, Any]:
        bookings = db.bookings()
        return {
            "visits": db.visit_counts(),
            "bookings": len(bookings),
            "control_seconds": sum((b[3] or time.time()) - b[2] for b in bookings),
        }

    @app.get("/api/admin/stream/{name}")
    def admin_stream(_: Staff, name: str) -> dict[str, Any]:
        """Server-side delay from sampling a state to handing its frame to each client's socket, and
        how far the people the viewers were shown stood from the tracker's estimates."""
        hub = hub_for(name)
        delays = sorted(hub.send_delays)
        people = hub.stream.fidelity.summary()
        robot_time = None if hub.view is None else hub.view.t  # the robot's own clock (simulated time)
        if not delays:
            return {"frames": 0, "people_shown": people, "robot_time_s": robot_time}
        return {
            "people_shown": people,
            "robot_time_s": robot_time,
            "frames": len(delays),
            "p50_ms": 1000 * delays[len(delays) // 2],
            "p99_ms": 1000 * delays[min(len(delays) - 1, int(0.99 * len(delays)))],
        }

    @app.delete("/api/admin/stream/{name}")
    def admin_stream_reset(_: Staff, name: str) -> dict[str, Any]:
        hub = hub_for(name)
        hub.send_delays.clear()
        hub.stream.reset_fidelity()
        return {"ok": True, "robot_time_s": None if hub.view is None else hub.view.t}

    @app.get("/api/admin/robots/{name}/chat")
    def admin_chat(_: Staff, name: str) -> dict[str, Any]:
        """The robot's latest messages, and whether a visitor is in control to write to."""
        hub = hub_for(name)
        holder = hub.arbiter.holder
        return {
            "holder": holder is not None,
            "messages": [
                {**m.as_dict(), "current": m.session == holder} for m in db.messages(hub.robot_id, limit=50)
            ],
        }

    @app.post("/api/admin/robots/{name}/chat")
    async def admin_chat_reply(staff: Staff, name: str, body: _ChatIn) -> dict[str, Any]:
        """A staff member writes to the visitor in control of the robot."""
        hub = hub_for(name)
        if not _chat_allowed(staff, cfg.guard):
            raise HTTPException(429, "too many messages: slow down")
        holder = hub.arbiter.holder
        if holder is None:
            raise HTTPException(409, "no visitor is in control of this robot")
        item = await hub.post_chat(holder, "staff", body.text)
        return item.as_dict()

    @app.post("/api/robots/{name}/staff-stop")
    async def staff_stop(_: Staff, name: str) -> dict[str, bool]:
        hub = hub_for(name)
        hub.arbiter.staff_stop()  # web commands are refused from now on, whatever the robot says
        try:
            await hub.command(lambda link: link.stop())
        except TourbotError:
            raise HTTPException(503, "the robot did not answer; web control is stopped") from None
        await hub.announce("Stopped by staff.")
        return {"ok": True}

    @app.post("/api/robots/{name}/staff-release")
    async def staff_release(_: Staff, name: str) -> dict[str, bool]:
        hub = hub_for(name)
        hub.arbiter.staff_release()
        await hub.slot_changed()
        return {"ok": True}

    # --- live stream and commands ----------------------------------------------------------
    @app.websocket("/ws/{name}")
    async def live(ws: WebSocket, name: str) -> None:
        if not origin_allowed(ws.headers.get("origin"), ws.headers.get("host"), cfg.allowed_origins):
            await ws.close(code=1008, reason="origin not allowed")
            return
        client = await asyncio.to_thread(lookup, ws.cookies.get(COOKIE))
        if client is None:
            await ws.close(code=1008, reason="no session: load the page first")
            return
        if name not in hubs:
            await ws.close(code=1008, reason="no such robot")
            return
        hub = hubs[name]
        host = ws.client.host if ws.client else "?"
        onboard = ws.query_params.get("screen") == "onboard"
        if onboard and not is_onboard(client):
            await ws.close(code=1008, reason="the on-board screen is for the paired robot screen")
            return
        debug = ws.query_params.get("debug") == "truth"  # the page's labelled debug overlay
        await ws.accept()
        await hub.connect(client.session)
        hub.debug_viewers += debug
        phrasebook = _phrasebook(hub, cfg, db) if onboard else None
        tasks = [asyncio.create_task(_send_loop(ws, hub, client, onboard, debug))]
        viewer = _stream_viewer(ws, tasks)
        try:
            await ws.send_text(json.dumps({"type": "hello", "robot": name, "session": client.session}))
            hub.watch(viewer)  # the stream's frames come from the hub from here on
            await _receive_loop(ws, hub, client, cfg, db, buckets, phrasebook, host)
        except WebSocketDisconnect:
            pass
        finally:
            hub.unwatch(viewer)
            for task in tasks:
                task.cancel()
            for task in tasks:
                with suppress(asyncio.CancelledError, Exception):
                    await task
            hub.debug_viewers -= debug
            await hub.disconnect(client.session)

    return app


def _phrasebook(hub: RobotHub, cfg: WebConfig, db: Database) -> PhraseBook:
    return PhraseBook(
        robot=hub.name.capitalize(),
        site=cfg.site_name,
        tours=[t.name for t in db.tours()],
        exhibits={e.slug: e.name for e in db.exhibits()},
    )


class _Mailbox:
    """The stream of one connection whose server cannot write prebuilt frames (the test client,
    another ASGI server): the connection's task sends one message at a time, and while one is on
    its way the viewer does not take another (it is skipped as a full socket buffer is, and gets
    a keyframe of a later state)."""

    def __init__(self) -> None:
        self.message: bytes | None = None
        self.ready = asyncio.Event()

    def offer(self, message: bytes, _frame: bytes) -> bool:
        if self.message is not None:
            return False
        self.message = message
        self.ready.set()
        return True

    async def run(self, ws: WebSocket) -> None:
        while True:
            await self.ready.wait()
            self.ready.clear()
            if self.message is not None:
                await ws.send_bytes(self.message)
                self.message = None


def _stream_viewer(ws: WebSocket, tasks: list[asyncio.Task[None]]) -> StreamViewer:
    """The connection as a viewer of the hub's stream: the server's frame writer
    (:mod:`tourbot.web.shared_frames`) when it offers one, else a :class:`_Mailbox` and its task."""
    offered = ws.scope.get("extensions", {}).get(FRAME_KEY)
    if offered is not None:
        write_frame = offered["write"]
        return StreamViewer(lambda _message, frame: bool(write_frame(frame)))
    mailbox = _Mailbox()
    tasks.append(asyncio.create_task(mailbox.run(ws)))
    return StreamViewer(mailbox.offer)


async def _send_loop(
    ws: WebSocket, hub: RobotHub, client: _Client, onboard: bool, debug: bool = False
) -> None:
    """The JSON texts to one client (the stream's frames come from the hub, see
    :meth:`RobotHub.watch`): woken when a text may have changed, or at every state for the on-board
    screen (its face follows the robot), it sends what this client has not had yet.

    Everything common to the viewers (the navigation status, the path message) is made once per
    state by the hub; here only this client's slot is looked at. A page's status is sent on change
    and at most once per ``hub.status_period`` (the changes in between are folded into the next
    one), except a change of this client's own role (it was given the robot, or lost it), which is
    sent at once: other visitors joining and leaving the queue cannot flood every viewer's link.
    The on-board screen (the robot's own, not on the web's link) gets every state for its face.
    """
    seen = -1
    last_status: dict[str, Any] | None = None
    status_key: tuple[int, bool] | None = None  # what the last status was made from
    status_at = -math.inf  # when the last status was sent (monotonic s)
    due_at: float | None = None  # a status change waiting for the status period to pass
    sent_path: str | None = None
    sent_obstacles: str | None = None
    sent_objects: str | None = None
    sent_robots: str | None = None
    sent_truth: str | None = None
    said = hub.announcements[-1].seq if hub.announcements else 0
    chat_seen = 0  # this visitor's conversation is sent from its start (a reload keeps it)
    while ws.application_state == WebSocketState.CONNECTED:
        if onboard:
            seen = await hub.wait_change(seen)
        else:
            wait = None if due_at is None else max(0.0, due_at - time.monotonic())
            seen = await hub.wait_texts(seen, wait)
        now = time.time()
        key = (hub.status_version, hub.arbiter.onboard_active(now))
        if key != status_key or onboard or due_at is not None:  # (the on-board face: every state)
            slot = hub.arbiter.view(client.session, now).as_dict()
            status: dict[str, Any] = {"type": "status", "slot": slot, "nav": hub.nav_status}
            if onboard:
                status["face"] = hub.face()
            comparable = {**status, "slot": {k: v for k, v in slot.items() if k != "time_left"}}
            early = time.monotonic() < status_at + hub.status_period
            own = last_status is None or slot["role"] != last_status["slot"]["role"]
            if comparable == last_status:
                status_key, due_at = key, None
            elif onboard or own or not early:
                await ws.send_text(json.dumps(status, separators=(",", ":")))
                last_status, status_key, due_at = comparable, key, None
                status_at = time.monotonic()
            elif due_at is None:
                due_at = status_at + hub.status_period
        path = hub.path_message
        if path is not None and path is not sent_path:
            await ws.send_text(path)
            sent_path = path
        obstacles = hub.obstacles_message  # the forward camera's obstacles, only when they changed
        if obstacles is not None and obstacles is not sent_obstacles:
            await ws.send_text(obstacles)
            sent_obstacles = obstacles
        objects = hub.objects.message  # doors and furniture as estimated, only when they changed
        if objects is not None and objects is not sent_objects:
            await ws.send_text(objects)
            sent_objects = objects
        robots = hub.robots_message  # the museum's robots and their queues, only when they changed
        if robots is not None and robots is not sent_robots:
            await ws.send_text(robots)
            sent_robots = robots
        truth = hub.truth_message
        if debug and truth is not None and truth is not sent_truth:
            await ws.send_text(truth)
            sent_truth = truth
        for item in hub.announcements:
            if item.seq > said:
                audio = None if item.audio is None else f"/speech/{item.audio}"
                await ws.send_text(json.dumps({"type": "say", "text": item.text, "audio": audio}))
                said = item.seq
        for line in hub.chat:
            if line.id > chat_seen:
                chat_seen = line.id
                if onboard or line.session == client.session:
                    await ws.send_text(json.dumps({"type": "chat", **line.as_dict()}))


async def _reply(ws: WebSocket, kind: str, **fields: Any) -> None:
    await ws.send_text(json.dumps({"type": kind, **fields}))


async def _receive_loop(
    ws: WebSocket,
    hub: RobotHub,
    client: _Client,
    cfg: WebConfig,
    db: Database,
    buckets: dict[int, TokenBucket],
    phrasebook: PhraseBook | None,
    host: str,
) -> None:
    bucket = buckets.setdefault(client.session, TokenBucket(cfg.guard.commands_per_second, cfg.guard.burst))
    refused = 0
    while True:
        message = await ws.receive()
        if message["type"] == "websocket.disconnect":
            raise WebSocketDisconnect(message.get("code", 1000))
        raw = message.get("text") if message.get("text") is not None else message.get("bytes")
        now = time.time()
        if not bucket.allow(time.monotonic()):
            refused += 1
            await _reply(ws, "error", message="too many messages: slow down")
            if refused > 50:  # a client that ignores the limit is cut off
                await ws.close(code=1008, reason="rate limit")
                return
            continue
        try:
            command = parse_command(raw or b"", cfg.guard)
            answer = await _execute(command, hub, client, db, now, phrasebook, host, cfg.guard)
        except TourbotError as exc:
            # a command's error names the rule; the database's would quote the client's slug
            if isinstance(exc, CommandError):
                text = str(exc)
            elif isinstance(exc, DatabaseError):
                text = "no such exhibit or tour"
            else:  # the robot refused, or its process is restarting
                text = f"the robot cannot do that now: {str(exc)[:200]}"
            await _reply(ws, "error", message=text)
            continue
        if answer is not None:
            await ws.send_text(json.dumps(answer))


async def _execute(
    command: Any,
    hub: RobotHub,
    client: _Client,
    db: Database,
    now: float,
    phrasebook: PhraseBook | None,
    host: str = "?",
    guard: GuardConfig | None = None,
) -> dict[str, Any] | None:
    """Carry out one command; :class:`CommandError` when this client may not."""
    arbiter = hub.arbiter
    arbiter.seen(client.session, now)
    if isinstance(command, Ping):
        return None
    elsewhere = getattr(hub.link, "controlled_at", None)  # a follower server (web.fanout)
    if elsewhere is not None:
        raise CommandError(f"this server only shows the robot; to book and drive it, go to {elsewhere}")
    if isinstance(command, Book):
        if phrasebook is not None:
            raise CommandError("the on-board screen does not book slots: it always has precedence")
        if not arbiter.book(client.session, now, group=host):
            raise CommandError(
                f"this address already has {arbiter.config.places_per_group} places in the queue"
            )
        # one robot at a time: booking this one gives up a slot or a place at another
        for other in hub.museum:
            if other is not hub and client.session in (other.arbiter.holder, *other.arbiter.queue):
                other.arbiter.leave(client.session, now)
                await other.slot_changed()
        await hub.slot_changed()
        return {"type": "ack", "command": "book"}
    if isinstance(command, Leave):
        arbiter.leave(client.session, now)
        await hub.slot_changed()
        return {"type": "ack", "command": "leave"}
    if isinstance(command, Chat):
        return await _chat(command.text, hub, client, phrasebook is not None, guard or GuardConfig())
    if phrasebook is not None:
        if arbiter.staff_stopped:
            raise CommandError("the robot was stopped by staff")
        arbiter.onboard_touch(now)
        source = "onboard"
    else:
        if not arbiter.may_command(client.session, now):
            raise CommandError(_why_not(hub, client.session, now))
        source = "web"
    if isinstance(command, Say):
        if phrasebook is None:
            raise CommandError("phrases are understood on the on-board screen only")
        return await _understand(command.text, hub, client, db, now, phrasebook)
    if isinstance(command, GoTo):
        x, y, theta = command.x, command.y, command.theta
        await hub.command(lambda link: link.send_goal(x, y, theta))
    elif isinstance(command, GoToExhibit):
        exhibit = await asyncio.to_thread(db.exhibit, command.exhibit)
        await hub.command(lambda link: link.send_goal(exhibit.x, exhibit.y, exhibit.theta, exhibit.slug))
        await asyncio.to_thread(db.record_visit, exhibit.slug, hub.robot_id, source, now)
    elif isinstance(command, StartTour):
        tour = await asyncio.to_thread(db.tour, command.tour)
        stops = [await asyncio.to_thread(db.exhibit, slug) for slug in tour.exhibits]
        if not stops:
            raise CommandError(f"tour {tour.slug!r} has no exhibits")
        plan = [(e.slug, e.x, e.y, e.theta) for e in stops]
        await hub.command(lambda link: link.start_tour(tour.slug, plan))
    elif isinstance(command, Around):
        exhibit = await asyncio.to_thread(db.exhibit, command.exhibit)
        await hub.command(lambda link: link.around(exhibit.slug, exhibit.x, exhibit.y, exhibit.theta))
        await asyncio.to_thread(db.record_visit, exhibit.slug, hub.robot_id, source, now)
    elif isinstance(command, Stop):
        await hub.command(lambda link: link.stop())
    await hub.notify()
    return {"type": "ack", "command": command.type}


def _chat_allowed(client: _Client, guard: GuardConfig) -> bool:
    """The text channel's rate limit of one session (staff, visitor or on-board screen)."""
    if client.chat is None:
        client.chat = TokenBucket(guard.chat_per_minute / 60.0, guard.chat_burst)
    return client.chat.allow(time.monotonic())


async def _chat(
    text: str, hub: RobotHub, client: _Client, onboard: bool, guard: GuardConfig
) -> dict[str, Any]:
    """A message from the visitor in control to the people on site, or from the on-board screen
    back to that visitor."""
    text = "".join(c for c in text if c.isprintable() or c == " ").strip()
    if not text:
        raise CommandError("an empty message is not sent")
    if not _chat_allowed(client, guard):
        raise CommandError("too many messages: slow down")
    holder = hub.arbiter.holder
    if onboard:
        if holder is None:
            raise CommandError("no web visitor is in control to write to")
        await hub.post_chat(holder, "onboard", text)
    else:
        if holder != client.session:
            raise CommandError("only the visitor in control of the robot can write to the staff")
        await hub.post_chat(client.session, "visitor", text)
    return {"type": "ack", "command": "chat"}


def _why_not(hub: RobotHub, session: int, now: float) -> str:
    arbiter = hub.arbiter
    if arbiter.staff_stopped:
        return "the robot was stopped by staff"
    if arbiter.holder == session and arbiter.onboard_active(now):
        return "visitors beside the robot are using its screen: please wait"
    view = arbiter.view(session, now)
    if view.position:
        return f"you are number {view.position} in the queue"
    return "book a slot to control the robot"


async def _understand(
    text: str, hub: RobotHub, client: _Client, db: Database, now: float, book: PhraseBook
) -> dict[str, Any]:
    view = hub.view
    if view is not None:
        book.switch(EXHIBIT if view.nav.state == "arrived" else TOUR if view.nav.tour else IDLE)
    summary = ""
    if view is not None and view.nav.exhibit:
        with suppress(DatabaseError):
            summary = (await asyncio.to_thread(db.exhibit, view.nav.exhibit)).summary
    reply = book.understand(text, summary)
    if reply is None:
        item = await hub.announce("Sorry, I did not understand.")
        return {"type": "heard", "intent": None, "text": item.text}
    if reply.action == "exhibit" and reply.argument:
        await _execute(GoToExhibit(type="exhibit", exhibit=reply.argument), hub, client, db, now, book)
    elif reply.action == "tour":
        tours = await asyncio.to_thread(db.tours)
        if tours:
            await _execute(StartTour(type="tour", tour=tours[0].slug), hub, client, db, now, book)
    elif reply.action == "stop":
        await hub.command(lambda link: link.stop())
    await hub.announce(reply.text)
    return {"type": "heard", "intent": reply.intent, "text": reply.text}
