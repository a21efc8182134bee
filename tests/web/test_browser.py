"""The visitor page in a real browser (Debian's Chromium driven by Playwright)."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from tests.web.fakes import FakeRobot
from tests.web.live import LiveServer
from tourbot.maps.grid import OccupancyGrid
from tourbot.web.app import WebConfig, create_app, find_node_modules
from tourbot.web.db import Database, open_database

CHROMIUM = Path("/usr/bin/chromium")
PAIRING = "pair-the-robot-screen"
pytestmark = [
    pytest.mark.browser,
    pytest.mark.skipif(
        not CHROMIUM.exists(), reason="Debian's chromium is not installed at /usr/bin/chromium"
    ),
]
FLAGS = [
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--use-angle=swiftshader",
    "--enable-unsafe-swiftshader",
    "--autoplay-policy=no-user-gesture-required",
]


def _room() -> OccupancyGrid:
    """A 12 m x 8 m hall with walls, at 10 cm."""
    prob = np.zeros((80, 120), dtype=np.float32)
    prob[0, :] = prob[-1, :] = prob[:, 0] = prob[:, -1] = 1.0
    prob[40, 30:60] = 1.0
    return OccupancyGrid(prob, 0.1, (0.0, 0.0, 0.0))


@pytest.fixture
def site_db(sqlite_url: str) -> Database:
    db = open_database(sqlite_url)
    db.save_exhibit("amphora", "Amphora", x=9.0, y=2.0, text="A painted clay amphora.", summary="An amphora.")
    db.save_exhibit("loom", "Loom", x=3.0, y=6.0, text="A weaver's loom.")
    db.save_tour("short", "Short tour", ["amphora", "loom"])
    return db


@pytest.fixture
def server(site_db: Database, tmp_path: Path) -> Iterator[tuple[str, FakeRobot]]:
    if find_node_modules() is None:
        pytest.skip("three.js is not installed (npm ci)")
    robot = FakeRobot(speed=2.0)
    config = WebConfig(site_name="Test hall", speech_dir=tmp_path / "speech", onboard_token=PAIRING)
    with LiveServer(create_app({"lefkos": robot}, site_db, _room(), config)) as url:
        yield url, robot


@pytest.fixture
def browser() -> Iterator[Any]:
    sync_api = pytest.importorskip("playwright.sync_api")
    with sync_api.sync_playwright() as p:
        b = p.chromium.launch(executable_path=str(CHROMIUM), args=FLAGS, headless=True)
        yield b
        b.close()


class _Visitor:
    """A browser context (its own cookies: its own session) that refuses any non-local request."""

    def __init__(self, browser: Any, url: str) -> None:
        self.context = browser.new_context()
        self.outside: list[str] = []
        self.errors: list[str] = []
        self.context.route("**/*", self._route)
        self.page = self.context.new_page()
        self.page.on("pageerror", lambda e: self.errors.append(str(e)))
        self.page.goto(url)

    def _route(self, route: Any) -> None:
        address = route.request.url
        if address.startswith(("http://127.0.0.1:", "ws://127.0.0.1:")):
            route.continue_()
        else:
            self.outside.append(address)
            route.abort()

    def slot(self, role: str, timeout: float = 15000) -> None:
        self.page.wait_for_selector(f"#slot[data-role='{role}']", timeout=timeout)


def test_visitor_books_drives_to_an_exhibit_and_hands_over(
    server: tuple[str, FakeRobot], browser: Any
) -> None:
    url, robot = server
    first = _Visitor(browser, url)
    first.page.wait_for_selector("#exhibits button[data-exhibit='amphora']")
    first.page.click("#book")
    first.slot("holder")
    assert "You control the robot" in first.page.inner_text("#slot")
    first.page.click("#exhibits button[data-exhibit='amphora']")
    first.page.wait_for_function(
        "() => document.getElementById('state').textContent.includes('Arrived at Amphora')", timeout=20000
    )
    assert robot.commands[0] == ("goal", (9.0, 2.0, 0.0, "amphora"))
    assert abs(robot.x - 9.0) < 0.1
    assert "painted clay amphora" in first.page.inner_text("#info")
    # The robot drawn on the page is where the server says it is (stream decoded in the browser).
    shown = first.page.evaluate("() => window.tourbot.live.scene(0).find(b => b.id === 0)")
    assert abs(shown["x"] - robot.x) < 0.1

    second = _Visitor(browser, url)
    second.page.wait_for_selector("#book")
    second.page.click("#book")
    second.slot("queued")
    assert "number 1 in the queue" in second.page.inner_text("#slot")
    second.page.click("#exhibits button[data-exhibit='loom']")
    second.page.wait_for_function(
        "document.getElementById('messages').textContent.includes('Take control first')"
    )
    assert len(robot.commands) == 1
    first.page.reload()  # a reload keeps the slot
    first.slot("holder")
    second.slot("queued")
    first.page.click("#leave")  # the holder leaves: the slot passes on
    second.slot("holder")
    second.page.click("#exhibits button[data-exhibit='loom']")
    second.page.wait_for_function(
        "() => document.getElementById('state').textContent.includes('Arrived at Loom')", timeout=20000
    )
    assert robot.commands[-1][0] == "goal"
    for visitor in (first, second):
        assert visitor.outside == []
        assert visitor.errors == []


def test_a_click_while_the_connection_reopens_is_not_lost(
    server: tuple[str, FakeRobot], browser: Any
) -> None:
    """A visitor who clicks while the page's connection is down (just loaded, or dropped and
    reconnecting) gets what they asked for once it is up again."""
    url, _ = server
    visitor = _Visitor(browser, url)
    visitor.page.wait_for_function(
        "() => window.tourbot && window.tourbot.live && window.tourbot.live.ws.readyState === WebSocket.OPEN"
    )
    visitor.page.evaluate("() => window.tourbot.live.ws.close()")  # dropped: reconnects in 0.5 s
    visitor.page.click("#book")
    visitor.slot("holder")
    assert visitor.errors == []


def test_3d_view_really_draws(server: tuple[str, FakeRobot], browser: Any) -> None:
    url, _ = server
    visitor = _Visitor(browser, url)
    visitor.page.wait_for_function("() => window.tourbot && window.tourbot.view3d !== null", timeout=20000)
    visitor.page.wait_for_timeout(1500)
    info = visitor.page.evaluate(
        """() => {
            const canvas = document.getElementById('view3d');
            const gl = canvas.getContext('webgl2') || canvas.getContext('webgl');
            const copy = document.createElement('canvas');
            copy.width = canvas.width; copy.height = canvas.height;
            const ctx = copy.getContext('2d');
            ctx.drawImage(canvas, 0, 0);
            const data = ctx.getImageData(0, 0, copy.width, copy.height).data;
            const colours = new Set();
            for (let i = 0; i < data.length; i += 4 * 97) {
                colours.add(data[i] << 16 | data[i + 1] << 8 | data[i + 2]);
            }
            return {webgl: gl !== null, colours: colours.size, avatars: window.tourbot.view3d.avatars.size};
        }"""
    )
    assert info["webgl"]
    assert info["colours"] > 20, info
    assert info["avatars"] == 7
    for preset in ("robot", "follow", "orbit"):
        visitor.page.click(f"[data-preset='{preset}']")
    visitor.page.wait_for_timeout(300)
    assert visitor.outside == []
    assert visitor.errors == []


def test_onboard_screen_talks_and_staff_place_an_exhibit(
    server: tuple[str, FakeRobot], browser: Any, site_db: Database
) -> None:
    url, robot = server
    onboard = _Visitor(browser, url + f"/onboard/pair?token={PAIRING}")  # lands on /onboard
    onboard.page.wait_for_selector("#exhibits button[data-exhibit='loom']")
    onboard.page.wait_for_selector("#face[data-mood='happy']")
    onboard.page.fill("#phrase", "who are you?")
    onboard.page.click("#talk button")
    onboard.page.wait_for_function("() => document.getElementById('said').textContent.includes('Lefkos')")
    # The on-board screen has precedence: it moves the robot without a slot.
    onboard.page.click("#exhibits button[data-exhibit='loom']")
    onboard.page.wait_for_function(
        "() => document.getElementById('said').textContent.includes('Here is Loom')", timeout=20000
    )
    assert robot.commands[-1] == ("goal", (3.0, 6.0, 0.0, "loom"))
    audio = onboard.page.evaluate("() => document.getElementById('voice').getAttribute('src')")
    if audio is not None:  # espeak-ng installed: the page got a WAV file to play
        response = onboard.context.request.get(url + audio)
        assert response.status == 200
        assert response.body()[:4] == b"RIFF"

    staff = _Visitor(browser, url + "/admin")
    site_db.set_staff("curator", "correct horse")
    staff.page.fill("#username", "curator")
    staff.page.fill("#password", "correct horse")
    staff.page.click("#login button")
    staff.page.wait_for_selector("#work:not([hidden])")
    staff.page.fill("#exhibit [name=slug]", "lyre")
    staff.page.fill("#exhibit [name=name]", "Lyre")
    box = staff.page.locator("#map").bounding_box()
    staff.page.mouse.click(box["x"] + box["width"] * 0.5, box["y"] + box["height"] * 0.5)
    staff.page.click("#exhibit button:not([type])")
    staff.page.wait_for_function(
        "() => document.getElementById('message').textContent.includes('saved lyre')"
    )
    lyre = site_db.exhibit("lyre")
    assert 0.0 < lyre.x < 12.0
    assert 0.0 < lyre.y < 8.0
    for page in (onboard, staff):
        assert page.outside == []
        assert page.errors == []


def test_staff_edit_an_exhibit_placed_to_the_millimetre(
    server: tuple[str, FakeRobot], browser: Any, site_db: Database
) -> None:
    # `tourbot site new` and imported sites place exhibits to the millimetre, with a heading: the
    # form must save them as they are (a step of 0.01 blocked the form without a word)
    site_db.save_exhibit("stop-1", "Stop 1", x=7.123, y=2.987, theta=-1.5852)
    url, _ = server
    site_db.set_staff("curator", "correct horse")
    staff = _Visitor(browser, url + "/admin")
    console: list[str] = []
    staff.page.on("console", lambda m: console.append(m.text))
    staff.page.fill("#username", "curator")
    staff.page.fill("#password", "correct horse")
    staff.page.click("#login button")
    staff.page.wait_for_selector("#work:not([hidden])")
    staff.page.click("#exhibits tr:has-text('stop-1')")
    staff.page.fill("#exhibit [name=name]", "The first exhibit")
    staff.page.click("#exhibit button:not([type])")
    staff.page.wait_for_function(
        "() => document.getElementById('message').textContent.includes('saved stop-1')", timeout=10000
    )
    saved = site_db.exhibit("stop-1")
    assert saved.name == "The first exhibit"
    assert (saved.x, saved.y, saved.theta) == pytest.approx((7.123, 2.987, -1.5852))
    assert not [m for m in console if "not a valid regular expression" in m]  # the slug's pattern
    assert staff.errors == []


@pytest.mark.slow
def test_visitor_sends_the_simulated_robot_to_an_exhibit(
    browser: Any, sqlite_url: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The real thing, no fake robot: the FHW museum simulated with visitors, MCL and the navigator
    in the robot's own process (4x real time, so that the test stays short), served as by
    ``tourbot demo``. A visitor books, sends the robot to the Alexander map (12 m away), sees it
    arrive, and the robot drawn on the page stands at the exhibit; a picture of its camera comes at
    full size, and moving around the exhibit takes it to the next viewpoint."""
    from tourbot.localization.profile import FHW_PROFILE, LocalizationProfile
    from tourbot.web.serve import ServeSettings, build_site_app

    if find_node_modules() is None:
        pytest.skip("three.js is not installed (npm ci)")
    monkeypatch.chdir(tmp_path)
    mcl = LocalizationProfile.load(FHW_PROFILE).mcl.with_samples(200)  # the site's profile
    settings = ServeSettings(
        site="fhw", database=sqlite_url, crowd="5", mcl=mcl, speedup=4.0,
        staff_password="s3cret-pass", speech_dir=tmp_path / "speech",
    )  # fmt: skip
    app, db = build_site_app(settings)
    target = db.exhibit("alexander-map")
    with LiveServer(app) as url:
        visitor = _Visitor(browser, url)
        visitor.page.wait_for_selector("#exhibits button[data-exhibit='alexander-map']", timeout=30000)
        visitor.page.click("#book")
        visitor.slot("holder", timeout=30000)
        visitor.page.click("#exhibits button[data-exhibit='alexander-map']")
        visitor.page.wait_for_function(
            f"() => document.getElementById('state').textContent.includes('Arrived at {target.name}')",
            timeout=90000,
        )
        shown = visitor.page.evaluate("() => window.tourbot.live.scene(0).find(b => b.id === 0)")
        # the estimated pose the robot acts on, at the exhibit's viewing pose (navigator's tolerance)
        assert abs(shown["x"] - target.x) < 0.6, shown
        assert abs(shown["y"] - target.y) < 0.6, shown
        # the robot's process renders its forward camera at 1280 x 960 where it stands
        visitor.page.click("#photo-button")
        visitor.page.wait_for_function(
            "() => document.getElementById('photo').naturalWidth > 0", timeout=30000
        )
        assert visitor.page.evaluate("() => [photo.naturalWidth, photo.naturalHeight]") == [1280, 960]
        # ... and goes round the exhibit, viewpoint after viewpoint
        visitor.page.click("#info [data-around='alexander-map']")
        visitor.page.wait_for_function(
            "() => /tour around alexander-map, [1-9]/.test(document.getElementById('state').textContent)",
            timeout=90000,
        )
        assert visitor.outside == []
        assert visitor.errors == []


@pytest.fixture
def museum(sqlite_url: str, tmp_path: Path) -> Iterator[tuple[str, FakeRobot]]:
    """The FHW museum's real (scanned) map and its exhibits, the fake robot at an exhibit."""
    from tourbot.site.default import site_path
    from tourbot.site.model import load_site
    from tourbot.web.sitedata import import_site

    if find_node_modules() is None:
        pytest.skip("three.js is not installed (npm ci)")
    site = load_site(site_path("fhw"))
    db = open_database(sqlite_url)
    import_site(site, db)
    robot = FakeRobot(speed=0.0)
    first = db.exhibits()[3]
    robot.x, robot.y = first.x, first.y
    config = WebConfig(site_name="FHW", speech_dir=tmp_path / "speech")
    with LiveServer(create_app({"lefkos": robot}, db, site.grid, config)) as url:
        yield url, robot


_LAYOUT = """() => {
    const t = window.tourbot, map = t.map, v = t.view3d;
    const box = (e) => {
        const r = e.getBoundingClientRect();
        return {x: r.left, y: r.top + scrollY, w: r.width, h: r.height};
    };
    const sections = [...document.querySelectorAll('main > section')].map(box)
        .filter((b) => b.w > 0 && b.h > 0);
    const canvas = document.getElementById('map');
    const k = map.scale;
    const [cw, ch] = map.cropSize;
    const [w, h] = map.turned ? [ch, cw] : [cw, ch];
    const robot = t.live.scene(0).find((b) => b.id === 0);
    const [ux, uy] = map.screenUp;
    const ahead = robot && map.toCanvas(robot.x + 3 * ux, robot.y + 3 * uy);
    const here = robot && map.toCanvas(robot.x, robot.y);
    return {
        viewport: innerWidth, scrollWidth: document.documentElement.scrollWidth, sections,
        map: box(canvas), fill: (w * k * h * k) / (canvas.width * canvas.height),
        canvas: {w: canvas.width, h: canvas.height}, labels: map.labels, exhibits: t.site.exhibits.length,
        robotAt: map.robotAt, up2d: robot && [ahead[0] - here[0], ahead[1] - here[1]],
        robot3d: robot && v.project(robot.x, robot.y, 0.5),
        up3d: robot && v.project(robot.x + 3 * ux, robot.y + 3 * uy, 0.5),
        view3d: box(document.getElementById('view3d')),
    };
}"""


def _overlap(a: dict[str, float], b: dict[str, float]) -> bool:
    return (
        a["x"] < b["x"] + b["w"] - 0.5
        and b["x"] < a["x"] + a["w"] - 0.5
        and (a["y"] < b["y"] + b["h"] - 0.5 and b["y"] < a["y"] + a["h"] - 0.5)
    )


@pytest.mark.parametrize(("width", "height"), [(390, 844), (1440, 900)], ids=["phone", "desktop"])
def test_visitor_page_layout_rules(
    museum: tuple[str, FakeRobot], browser: Any, tmp_path: Path, width: int, height: int
) -> None:
    """At a phone's and a desktop's size: nothing wider than the screen, no section over another,
    the 2D map filling its canvas with labels that never overlap and the robot on it, the 3D view
    framing the robot and turned like the 2D map (up on the map is up in the 3D view)."""
    url, _ = museum
    context = browser.new_context(viewport={"width": width, "height": height}, device_scale_factor=1)
    page = context.new_page()
    errors: list[str] = []
    page.on("pageerror", lambda e: errors.append(str(e)))
    page.goto(url)
    page.wait_for_function(
        "() => window.tourbot && window.tourbot.view3d && window.tourbot.map.robotAt", timeout=30000
    )
    page.wait_for_timeout(1500)
    shots = Path(__import__("os").environ.get("TOURBOT_SCREENSHOTS", tmp_path))
    shots.mkdir(parents=True, exist_ok=True)
    page.screenshot(path=str(shots / f"visitor-{width}x{height}.png"), full_page=True)
    got = page.evaluate(_LAYOUT)
    assert got["viewport"] == width
    assert got["scrollWidth"] <= width, "the page is wider than the screen"
    sections = got["sections"]
    assert len(sections) == 6
    for i, a in enumerate(sections):
        assert a["x"] >= 0
        assert a["x"] + a["w"] <= width + 0.5
        for b in sections[i + 1 :]:
            assert not _overlap(a, b), (a, b)
    assert got["map"]["w"] <= width
    assert got["fill"] > 0.9, got["fill"]  # the map fills its canvas
    labels = got["labels"]
    assert len(labels) >= got["exhibits"] // 2
    for i, a in enumerate(labels):
        assert a["x"] >= 0
        assert a["x"] + a["w"] <= got["canvas"]["w"]
        assert a["y"] >= 0
        assert a["y"] + a["h"] <= got["canvas"]["h"]
        for b in labels[i + 1 :]:
            assert not _overlap(a, b), (a, b)
    robot = got["robotAt"]
    assert 0 < robot["x"] < got["canvas"]["w"]
    assert 0 < robot["y"] < got["canvas"]["h"]
    dx, dy = got["up2d"]
    assert dy < 0  # screenUp is up on the 2D map
    assert abs(dx) < 1
    r3, u3 = got["robot3d"], got["up3d"]
    assert abs(r3["x"]) < 0.8, r3  # the default 3D view frames the robot
    assert abs(r3["y"]) < 0.8, r3
    assert u3["y"] > r3["y"] + 0.05  # ... and shows the map's up as up
    assert abs(u3["x"] - r3["x"]) < 0.05
    assert got["view3d"]["w"] <= width
    assert errors == []
    context.close()


def test_status_messages_are_not_repeated(server: tuple[str, FakeRobot], browser: Any) -> None:
    url, _ = server
    visitor = _Visitor(browser, url)
    visitor.page.wait_for_function("() => window.tourbot && window.tourbot.live")
    lines = visitor.page.evaluate(
        """() => {
            const log = document.getElementById('messages');
            log.replaceChildren();
            for (let i = 0; i < 10; i++) {
                window.tourbot.message('moving: Amphora');
                window.tourbot.message('blocked: Amphora');
            }
            window.tourbot.message('Arrived at Amphora');
            return [...log.children].map((n) => n.textContent);
        }"""
    )
    assert len(lines) == 3
    assert "Arrived at Amphora" in lines[0]
    assert "×10" in lines[1] or "×10" in lines[2]


@pytest.fixture
def two_robots(site_db: Database, tmp_path: Path) -> Iterator[tuple[str, FakeRobot, FakeRobot]]:
    """Two robots in one hall (WebFAIR), each with its own queue."""
    if find_node_modules() is None:
        pytest.skip("three.js is not installed (npm ci)")
    lefkos, albert = FakeRobot(speed=2.0), FakeRobot(speed=2.0)
    config = WebConfig(site_name="Test hall", speech_dir=tmp_path / "speech", onboard_token=PAIRING)
    with LiveServer(create_app({"lefkos": lefkos, "albert": albert}, site_db, _room(), config)) as url:
        yield url, lefkos, albert


def _option(visitor: _Visitor, robot: str) -> str:
    return str(visitor.page.locator(f"#robot option[value='{robot}']").inner_text())


def test_a_visitor_chooses_a_free_robot_while_another_is_driven(
    two_robots: tuple[str, FakeRobot, FakeRobot], browser: Any
) -> None:
    url, lefkos, albert = two_robots
    first = _Visitor(browser, url)
    first.page.wait_for_selector("#exhibits button[data-exhibit='amphora']")
    first.page.click("#book")
    first.slot("holder")
    second = _Visitor(browser, url)
    # the list says which robot is driven and which is free (refreshed every 5 s)
    second.page.wait_for_function(
        "() => document.querySelector(\"#robot option[value='lefkos']\")?.textContent.includes('driven')",
        timeout=15000,
    )
    assert "free" in _option(second, "albert")
    assert second.page.input_value("#robot") == "lefkos"
    second.page.select_option("#robot", "albert")
    second.page.wait_for_url("**/?robot=albert")
    second.page.wait_for_selector("#exhibits button[data-exhibit='loom']")
    second.page.click("#book")
    second.slot("holder")  # albert's queue: not behind lefkos' holder
    second.page.click("#exhibits button[data-exhibit='loom']")
    second.page.wait_for_function(
        "() => document.getElementById('state').textContent.includes('Arrived at Loom')", timeout=20000
    )
    assert albert.commands == [("goal", (3.0, 6.0, 0.0, "loom"))]
    assert lefkos.commands == []
    shown = second.page.evaluate("() => window.tourbot.live.scene(0).find(b => b.id === 0)")
    assert abs(shown["x"] - albert.x) < 0.1  # the page follows the robot chosen
    first.page.wait_for_function(
        "() => document.querySelector(\"#robot option[value='albert']\")?.textContent.includes('driven')",
        timeout=15000,
    )
    for visitor in (first, second):
        assert visitor.outside == []
        assert visitor.errors == []


def test_the_holder_and_the_staff_talk_as_text(
    server: tuple[str, FakeRobot], browser: Any, site_db: Database
) -> None:
    """The text channel in the pages: the visitor in control writes, the staff page shows it as text
    (markup in it stays text), the staff answer, the visitor's page shows the answer; the robot's
    own screen shows both and answers too."""
    url, _ = server
    visitor = _Visitor(browser, url)
    visitor.page.wait_for_selector("#book")
    assert visitor.page.is_disabled("#chat-text")  # only the visitor in control writes
    visitor.page.click("#book")
    visitor.slot("holder")
    onboard = _Visitor(browser, url + f"/onboard/pair?token={PAIRING}")
    onboard.page.wait_for_selector("#face[data-mood='happy']")
    dialogs: list[str] = []

    def on_dialog(dialog: Any) -> None:
        dialogs.append(dialog.message)
        dialog.dismiss()

    attack = "<img src=x onerror=\"document.title='owned'\"> Where is the loom?"
    visitor.page.fill("#chat-text", attack)
    visitor.page.click("#chat button")
    visitor.page.wait_for_function("() => document.querySelectorAll('#chat-log .chat-line').length === 1")

    staff = _Visitor(browser, url + "/admin")
    for page in (visitor, onboard, staff):
        page.page.on("dialog", on_dialog)
    site_db.set_staff("curator", "correct horse")
    staff.page.fill("#username", "curator")
    staff.page.fill("#password", "correct horse")
    staff.page.click("#login button")
    staff.page.wait_for_selector("#talk:not([hidden])")
    staff.page.wait_for_function(
        "() => document.getElementById('chat-log').textContent.includes('Where is the loom?')", timeout=10000
    )
    line = staff.page.locator("#chat-log .chat-line").first
    assert attack in line.inner_text()
    assert staff.page.locator("#chat-log img").count() == 0  # shown as text, not as markup
    staff.page.fill("#chat-text", "Behind you, on the left.")
    staff.page.click("#chat button")
    visitor.page.wait_for_function(
        "() => document.getElementById('chat-log').textContent.includes('Staff: Behind you, on the left.')",
        timeout=10000,
    )
    onboard.page.wait_for_function(
        "() => document.getElementById('chat-log').textContent.includes('Behind you')", timeout=10000
    )
    assert "Where is the loom?" in onboard.page.inner_text("#chat-log")
    assert onboard.page.locator("#chat-log img").count() == 0
    onboard.page.fill("#chat-text", "Waving at you now!")
    onboard.page.click("#chat button")
    visitor.page.wait_for_function(
        "() => document.getElementById('chat-log').textContent.includes('At the robot: Waving at you now!')",
        timeout=10000,
    )
    visitor.page.reload()  # the conversation is kept over a reload, each line once
    visitor.page.wait_for_function("() => document.querySelectorAll('#chat-log .chat-line').length === 3")
    assert visitor.page.locator("#chat-log img").count() == 0
    for page in (visitor, staff, onboard):
        assert page.page.title() != "owned"
        assert page.outside == []
        assert page.errors == []
    assert dialogs == []


def test_the_holder_takes_a_picture_and_moves_around_an_exhibit(
    server: tuple[str, FakeRobot], browser: Any
) -> None:
    url, robot = server
    watcher = _Visitor(browser, url)
    watcher.page.wait_for_selector("#book")
    watcher.page.click("#photo-button")
    watcher.page.wait_for_function(
        "() => document.getElementById('messages').textContent.includes('Take control first')"
    )
    assert watcher.page.is_hidden("#photo-box")
    visitor = _Visitor(browser, url)
    visitor.page.wait_for_selector("#book")
    visitor.page.click("#book")
    visitor.slot("holder")
    visitor.page.click("#photo-button")
    visitor.page.wait_for_selector("#photo-box:not([hidden])")
    visitor.page.wait_for_function("() => document.getElementById('photo').naturalWidth > 0")
    size = visitor.page.evaluate("() => [photo.naturalWidth, photo.naturalHeight]")
    assert size == [64, 48]  # the robot's JPEG, decoded by the browser
    visitor.page.click("#photo-button")  # at once again: one picture per 5 s
    visitor.page.wait_for_function(
        "() => document.getElementById('messages').textContent.includes('No picture: one picture at a time')"
    )
    visitor.page.click("#exhibits button[data-exhibit='amphora']")
    visitor.page.click("#info [data-around='amphora']")
    visitor.page.wait_for_function(
        "() => document.getElementById('state').textContent.includes('tour around amphora')", timeout=10000
    )
    assert robot.commands[-1] == ("around", "amphora")
    assert [c for c in robot.commands if c[0] == "photo"] == [("photo", None)]
    for page in (watcher, visitor):
        assert page.outside == []
        assert page.errors == []


def test_vision_obstacles_are_drawn_in_their_own_colour(server: tuple[str, FakeRobot], browser: Any) -> None:
    """A table the laser does not see, found by the robot's forward camera: orange cells on the map
    where it stands, and nothing orange elsewhere."""
    url, robot = server
    robot.n_people = 0  # the fake's visitors walk a circle through the table's cells
    table = tuple((6.0 + 0.1 * i, 3.0 + 0.1 * j) for i in range(6) for j in range(4))
    visitor = _Visitor(browser, url)
    visitor.page.wait_for_function("() => window.tourbot && window.tourbot.map && window.tourbot.live")
    colours = """(points) => {
        const map = window.tourbot.map;
        const context = map.canvas.getContext('2d');
        return points.map(([x, y]) => {
            const [px, py] = map.toCanvas(x, y);
            const [r, g, b] = context.getImageData(Math.round(px), Math.round(py), 1, 1).data;
            return [r, g, b];
        });
    }"""

    def orange(rgb: list[int]) -> bool:  # #f60 at 80 % over the floor
        r, g, b = rgb
        return r > 200 and r - g > 60 and r - b > 120

    centres = [list(p) for p in table]  # the cells' centres
    before = visitor.page.evaluate(colours, centres)
    assert sum(map(orange, before)) == 0
    robot.obstacles = table
    visitor.page.wait_for_function("() => window.tourbot.map.obstacles.length === 24", timeout=15000)
    visitor.page.wait_for_timeout(500)  # a frame drawn since
    after = visitor.page.evaluate(colours, centres)
    assert all(map(orange, after)), list(zip(centres, after, strict=True))
    far = visitor.page.evaluate(colours, [[9.0, 6.5]])[0]
    assert far[2] > 150  # floor far from the table: not orange
    assert not visitor.errors


def _leaf(angle: float) -> Any:
    """A 0.9 m door leaf hinged at (7, 6), ``angle`` from closed (along +x), as the web gets it."""
    import math

    from tourbot.web.link import ObjectView

    c, s = math.cos(angle), math.sin(angle)
    local = [(0.0, -0.02), (0.9, -0.02), (0.9, 0.02), (0.0, 0.02)]
    outline = tuple((7.0 + c * x - s * y, 6.0 + s * x + c * y) for x, y in local)
    return ObjectView("office-door", "door", outline)


_DOOR_PIXELS = """([points]) => {
    const map = window.tourbot.map, ctx = document.getElementById('map').getContext('2d');
    return points.map(([x, y]) => {
        const [px, py] = map.toCanvas(x, y);
        return Array.from(ctx.getImageData(Math.round(px), Math.round(py), 1, 1).data.slice(0, 3));
    });
}"""


def test_a_door_drawn_in_the_page_follows_its_estimated_state(
    server: tuple[str, FakeRobot], browser: Any
) -> None:
    """The door is drawn where the robot estimates it (2D map and 3D view), and redrawn when the
    estimate changes; an unchanged estimate sends nothing more."""
    import math

    url, robot = server
    robot.objects = (_leaf(0.0),)
    visitor = _Visitor(browser, url)
    visitor.page.wait_for_function(
        "() => window.tourbot && window.tourbot.map.objects.length === 1", timeout=20000
    )
    visitor.page.wait_for_timeout(300)
    closed_mid, open_mid = [7.45, 6.0], [7.0, 6.45]
    door = [0x7A, 0x3B, 0x0C]

    def near(rgb: list[int]) -> bool:
        return max(abs(a - b) for a, b in zip(rgb, door, strict=True)) < 30

    at_closed, at_open = visitor.page.evaluate(_DOOR_PIXELS, [[closed_mid, open_mid]])
    assert near(at_closed), at_closed
    assert not near(at_open), at_open
    counted = """() => {
        const h = window.tourbot.live.handlers, draw = h.onObjects;
        window.objectMessages = 0;
        h.onObjects = (objects) => { window.objectMessages += 1; draw(objects); };
    }"""
    visitor.page.evaluate(counted)
    visitor.page.wait_for_timeout(1000)
    assert visitor.page.evaluate("() => window.objectMessages") == 0  # the same estimate: nothing sent
    robot.objects = (_leaf(math.pi / 2),)
    visitor.page.wait_for_function(
        "() => Math.abs(window.tourbot.map.objects[0].outline[1][1] - 6.9) < 0.05", timeout=10000
    )
    visitor.page.wait_for_timeout(300)
    at_closed, at_open = visitor.page.evaluate(_DOOR_PIXELS, [[closed_mid, open_mid]])
    assert near(at_open), at_open
    assert not near(at_closed), at_closed
    assert visitor.page.evaluate("() => window.objectMessages") == 1
    if visitor.page.evaluate("() => window.tourbot.view3d !== null"):
        box = visitor.page.evaluate(
            """() => {
                const mesh = window.tourbot.view3d.objects.children[0];
                mesh.geometry.computeBoundingBox();
                const b = mesh.geometry.boundingBox;
                return [b.min.x, b.min.y, b.max.x, b.max.y];
            }"""
        )
        assert box[3] - box[1] > 0.8  # the leaf stands along +y now in the 3D view too
        assert box[2] - box[0] < 0.1
    assert visitor.errors == []
