"""``tourbot bench web``: the live stream's bandwidth, 200 viewers, and command-to-motion latency.

Burgard et al. (section 6.1.1): a 240x180 video stream at about 5 Hz needed about 40 kbit/s, the
graphics-based view about 1 kbit/s with 7 people around the robot. Here the server runs as its
own process (``tourbot serve`` on the simulated site) and the bench is its visitors:

1. bandwidth: one viewer behind a loopback relay that counts every byte the server sends (TCP
   payload: WebSocket framing and per-message deflate included, TCP/IP headers not), with the
   robot on a tour and 7 people;
2. 200 concurrent viewers, spread over worker processes: the delay from the server sampling a
   state to a viewer holding it (p50/p99), and the CPU of the web process, the robot's process
   and the viewers;
3. the slot holder's command-to-motion latency on loopback: from sending ``goto`` to the first
   streamed state in which the robot moves (drives or turns: it turns towards its path first).
"""

from __future__ import annotations

import asyncio
import json
import math
import os
import socket
import struct
import subprocess
import sys
import tempfile
import time
from contextlib import suppress
from pathlib import Path
from typing import Annotated, Any

import typer

from tourbot.geometry import wrap_angle

__all__ = ["CHROMIUM", "CHROMIUM_FLAGS", "ServedSite", "register"]

TARGET_KBIT = 1.0
TARGET_P99_MS = 100.0
PAPER_VIDEO_KBIT = 40.0
HEARTBEAT = 5.0  # s: the pages' ping (static/live.js)
STAFF_PASSWORD = "bench-password"  # the served site's staff password (the bench reads its figures)


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def _cpu_seconds(pid: int) -> float:
    """User + system CPU time of a process (Linux /proc)."""
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


class ServedSite:
    """``tourbot serve`` in a child process on a fresh SQLite file."""

    def __init__(
        self,
        site: str,
        crowd: str,
        seed: int,
        robots: int = 1,
        robot_process: bool = True,
        extra: tuple[str, ...] = (),
    ) -> None:
        self.port = _free_port()
        self.folder = tempfile.TemporaryDirectory(prefix="tourbot-bench-web-")
        db = f"sqlite:///{Path(self.folder.name) / 'site.db'}"
        command = [
            sys.executable, "-m", "tourbot", "serve", "--site", site, "--port", str(self.port),
            "--database", db, "--crowd", crowd, "--seed", str(seed), "--robots", str(robots),
            "--robot-process" if robot_process else "--robot-in-server", *extra,
        ]  # fmt: skip
        env = {
            **os.environ,
            "TOURBOT_STAFF_PASSWORD": STAFF_PASSWORD,
            "PYTHONPATH": os.pathsep.join([str(Path(__file__).parents[2]), *sys.path]),
        }
        self.process = subprocess.Popen(
            command, cwd=self.folder.name, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE
        )
        self.base = f"http://127.0.0.1:{self.port}"

    def wait(self, timeout: float = 600.0) -> None:
        """Until the server answers and its first robot's clock runs: a robot's process that is
        still starting (numba compiling its kernels on a fresh checkout takes minutes on a loaded
        machine) would otherwise stand still at the origin through the measurement."""
        import httpx

        deadline = time.monotonic() + timeout
        robot: str | None = None
        clock: float | None = None
        with httpx.Client(base_url=self.base, trust_env=False, timeout=5.0) as client:
            while time.monotonic() < deadline:
                if self.process.poll() is not None:
                    err = self.process.stderr.read().decode() if self.process.stderr else ""
                    raise typer.BadParameter(f"the server stopped: {err[-2000:]}")
                with suppress(httpx.HTTPError, KeyError, IndexError, ValueError):
                    if robot is None:
                        robot = str(client.get("/api/site").json()["robots"][0])
                        client.post("/api/login", json={"username": "staff", "password": STAFF_PASSWORD})
                    now = client.get(f"/api/admin/stream/{robot}").json()["robot_time_s"]
                    if now is not None and clock is not None and now > clock:
                        return
                    clock = now
                time.sleep(1.0)
        raise typer.BadParameter(f"the server's robot did not start within {timeout:.0f} s")

    def close(self) -> None:
        self.process.terminate()
        try:
            self.process.wait(15)
        except subprocess.TimeoutExpired:
            self.process.kill()
        self.folder.cleanup()


class _Broker:
    """A Redis server of the bench's own on loopback (no persistence), for ``--followers``."""

    def __init__(self) -> None:
        import shutil

        from tourbot.web.fanout import BrokerError, connect

        server = shutil.which("redis-server")
        if server is None:
            raise typer.BadParameter(
                "redis-server is missing (apt-get install redis-server)", param_hint="--followers"
            )
        self.port = _free_port()
        self.url = f"redis://127.0.0.1:{self.port}/0"
        self.process = subprocess.Popen(
            [server, "--port", str(self.port), "--bind", "127.0.0.1", "--save", "", "--appendonly", "no"],
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
        )
        deadline = time.monotonic() + 20.0
        while True:
            try:
                connect(self.url).close()
                return
            except BrokerError:
                if time.monotonic() > deadline:
                    self.close()
                    raise
                time.sleep(0.1)

    def close(self) -> None:
        self.process.terminate()
        self.process.wait(10)


async def _session(base: str) -> str:
    import httpx

    async with httpx.AsyncClient(base_url=base, trust_env=False) as client:
        response = await client.get("/api/session")
        return str(response.cookies["tourbot_session"])


class _Viewer:
    """A visitor's page without the page: the WebSocket, the decoder, timings."""

    def __init__(
        self,
        port: int,
        robot: str,
        stream: dict[str, float],
        origin_port: int | None = None,
        naive: bool = False,
    ) -> None:
        from tourbot.web.stream import StreamConfig, StreamDecoder

        self.port = port
        self.origin = f"http://127.0.0.1:{origin_port or port}"
        self.robot = robot
        self.decoder = StreamDecoder(
            StreamConfig(
                position_quantum=stream["position_quantum"],
                velocity_quantum=stream["velocity_quantum"],
                turn_quantum=stream["turn_quantum"],
                time_quantum=stream["time_quantum"],
                horizon=stream["horizon"],
            )
        )
        self.delays: list[tuple[float, float]] = []  # (received at, delay)
        self.naive = naive
        self._epoch = 0.0
        self._ticks = 0
        self.binary = self.text = 0
        self.naive_json = 0
        self.frames = 0
        self.ws: Any = None
        self.replies: asyncio.Queue[dict[str, Any]] = asyncio.Queue()
        self.on_frame: Any = None
        self.role = "watcher"
        self._ping_at = 0.0

    async def open(self, base: str, token: str | None = None) -> None:
        """Connect with a new session, or with ``token`` (many tabs of one browser: the server
        rate-limits new sessions per address, as it should against one machine's flood)."""
        from websockets.asyncio.client import connect

        token = token or await _session(base)
        self.ws = await connect(
            f"ws://127.0.0.1:{self.port}/ws/{self.robot}",
            origin=self.origin,  # type: ignore[arg-type]
            additional_headers={"Cookie": f"tourbot_session={token}"},
            proxy=None,
            max_queue=None,
            close_timeout=2,
        )

    async def run(self, until: float) -> None:
        """Read until ``until`` (monotonic s), with the page's heartbeat: a ping every
        ``HEARTBEAT`` seconds, without which a slot holder loses its slot after the server's
        answer timeout (20 s)."""
        while (now := time.monotonic()) < until:
            if now >= self._ping_at:
                self._ping_at = now + HEARTBEAT
                await self.send({"type": "ping"})
            wait = max(0.01, min(until, self._ping_at) - now)
            try:
                message = await asyncio.wait_for(self.ws.recv(), timeout=wait)
            except TimeoutError:
                continue
            now = time.time()
            if isinstance(message, bytes):
                self.binary += len(message)
                self.decoder.feed(message)
                self.frames += 1
                self.delays.append((now, now - self.decoder.t))
                if self.naive:
                    self.naive_json += len(_naive(self.decoder.scene()))
                if self.on_frame is not None:
                    self.on_frame(self.decoder.scene(), now)
            else:
                self.text += len(message)
                data = json.loads(message)
                if data.get("type") in ("ack", "error"):
                    self.replies.put_nowait(data)
                elif data.get("type") == "status":
                    self.role = data["slot"]["role"]

    async def watch(self) -> None:
        """Read until cancelled or closed, keeping only each frame's delay (no decoding: a
        many-viewer run must not measure its own work)."""
        from websockets.exceptions import ConnectionClosed

        with suppress(ConnectionClosed):
            async for message in self.ws:
                if isinstance(message, bytes):
                    now = time.time()
                    self.delays.append((now, now - self._stamp(message)))

    def _stamp(self, message: bytes) -> float:
        """Only the message's time (a many-viewer run must not measure its own decoding)."""
        if message[0] == 1:
            (self._epoch,) = struct.unpack_from("<d", message, 1)
            ticks = struct.unpack_from("<H", message, 9)[0]
            self._ticks = ticks
        else:
            ticks = struct.unpack_from("<H", message, 1)[0]
            self._ticks += (ticks - self._ticks) % 65536
        return self._epoch + self._ticks * 0.01

    async def send(self, command: dict[str, Any]) -> None:
        await self.ws.send(json.dumps(command))

    async def close(self) -> None:
        """Leave (a slot held is given up at once, not after the server's grace time) and close."""
        with suppress(Exception):
            await self.ws.send(json.dumps({"type": "leave"}))
            await self.ws.close()


def _naive(scene: Any) -> str:
    """The same state as plain JSON (what a rosbridge-style stream sends each frame)."""
    bodies = [scene.robot, *scene.people]
    return json.dumps(
        {
            "t": scene.t,
            "bodies": [
                {"id": b.id, "x": b.x, "y": b.y, "vx": b.vx, "vy": b.vy, "th": b.theta} for b in bodies
            ],
        }
    )


async def _relay(server_port: int) -> tuple[int, dict[str, int], asyncio.Server]:
    """A loopback TCP relay that counts the bytes flowing from the server to the client: in all
    (``total``), and apart on the WebSocket connections (``websocket``: those the server answered
    with ``101``) and the plain HTTP ones (``http``: pages, scripts, the pages' API calls)."""
    down = {"total": 0, "websocket": 0, "http": 0}

    async def pump(reader: asyncio.StreamReader, writer: asyncio.StreamWriter, count: bool) -> None:
        kind = None
        with suppress(ConnectionError):
            while data := await reader.read(65536):
                if count:
                    if kind is None:
                        kind = "websocket" if data.startswith(b"HTTP/1.1 101") else "http"
                    down["total"] += len(data)
                    down[kind] += len(data)
                writer.write(data)
                await writer.drain()
        writer.close()

    async def handle(client_r: asyncio.StreamReader, client_w: asyncio.StreamWriter) -> None:
        server_r, server_w = await asyncio.open_connection("127.0.0.1", server_port)
        await asyncio.gather(pump(client_r, server_w, False), pump(server_r, client_w, True))

    server = await asyncio.start_server(handle, "127.0.0.1", 0)
    port = int(server.sockets[0].getsockname()[1])
    return port, down, server


# Tallies in the page what each kind of message (the stream's keyframes and deltas, each JSON
# type) brings, as the page counts its payload (``window.tourbot.live.bytes``).
_TALLY = """() => {
  const live = window.tourbot.live;
  const tally = (window.benchTally = {});
  const receive = live.receive.bind(live);
  live.receive = (data) => {
    const binary = data instanceof ArrayBuffer;
    const kind = binary ? (new Uint8Array(data)[0] === 1 ? "keyframe" : "delta") : JSON.parse(data).type;
    const entry = tally[kind] || (tally[kind] = { bytes: 0, count: 0 });
    entry.bytes += binary ? data.byteLength : data.length;
    entry.count += 1;
    receive(data);
  };
}"""

CHROMIUM = Path("/usr/bin/chromium")
CHROMIUM_FLAGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
                   "--disable-background-networking", "--disable-component-update", "--disable-sync",
                   "--use-angle=swiftshader", "--enable-unsafe-swiftshader"]  # fmt: skip


async def _browser_bandwidth(server: ServedSite, seconds: float, warmup: float = 15.0) -> dict[str, Any]:
    """The visitor page in Chromium, loaded through the byte-counting relay: every byte the server
    sends to that page after ``warmup`` (page, scripts and keyframe loaded) for ``seconds``, the
    binary stream and the JSON texts (status, path, speech) alike, while a driver (not relayed)
    keeps the robot on a tour through the crowd."""
    from playwright.async_api import async_playwright

    if not CHROMIUM.exists():
        raise typer.BadParameter(f"{CHROMIUM} is missing (apt-get install chromium)", param_hint="--browser")
    site = await _site(server.base)
    robot = site["robots"][0]
    port, down, relay = await _relay(server.port)
    driver, tour = await _on_tour(server, site, robot)
    async with async_playwright() as p:
        browser = await p.chromium.launch(executable_path=str(CHROMIUM), args=CHROMIUM_FLAGS, headless=True)
        page = await browser.new_page()
        await page.goto(f"http://127.0.0.1:{port}/?robot={robot}")
        await page.wait_for_function(
            "() => window.tourbot && window.tourbot.live && window.tourbot.live.ws.readyState === 1",
            timeout=60000,
        )
        await page.evaluate(_TALLY)
        await driver.run(time.monotonic() + warmup)
        wire_start, page_start = dict(down), await page.evaluate("() => window.tourbot.live.bytes")
        texts_start = await page.evaluate("() => window.tourbot.live.texts")
        await page.evaluate("() => { for (const k in window.benchTally) delete window.benchTally[k]; }")
        # the shown people's error counted from here, and the robot's clock against the wall's
        robot_start = (await _staff(server, "DELETE", robot))["robot_time_s"]
        start = time.monotonic()
        people: list[int] = []
        while time.monotonic() < start + seconds:
            await driver.run(min(start + seconds, time.monotonic() + 5.0))
            people.append(await page.evaluate("() => window.tourbot.live.scene(0).length - 1"))
        elapsed = time.monotonic() - start
        wire = down["total"] - wire_start["total"]
        wire_http = down["http"] - wire_start["http"]
        payload = await page.evaluate("() => window.tourbot.live.bytes") - page_start
        texts = await page.evaluate("() => window.tourbot.live.texts") - texts_start
        messages = await page.evaluate("() => document.getElementById('messages').children.length")
        tally = await page.evaluate("() => window.benchTally")
        counted = await _staff(server, "GET", robot)
        fidelity = counted["people_shown"]
        await browser.close()
    await driver.close()
    relay.close()
    return {
        "seconds": elapsed,
        "wire_bytes": wire,
        "kbit_s": 8 * wire / elapsed / 1000,
        "http_kbit_s": 8 * wire_http / elapsed / 1000,
        "page_payload_kbit_s": 8 * payload / elapsed / 1000,
        "page_text_kbit_s": 8 * texts / elapsed / 1000,
        "people_shown_mean": sum(people) / max(1, len(people)),
        "people_shown_max": max(people, default=0),
        "people_error_mean_m": fidelity["mean_m"],
        "people_error_p95_m": fidelity["p95_m"],
        "people_unshown_fraction": fidelity["unshown"] / max(1, fidelity["unshown"] + fidelity["samples"]),
        "message_lines": messages,
        "tour": tour,
        "robot_seconds_per_second": math.nan
        if robot_start is None or counted.get("robot_time_s") is None
        else (counted["robot_time_s"] - robot_start) / elapsed,
        "by_type": {
            kind: {"kbit_s": 8 * n["bytes"] / elapsed / 1000, "per_minute": 60 * n["count"] / elapsed}
            for kind, n in sorted(tally.items())
        },
    }


async def _on_tour(server: ServedSite, site: dict[str, Any], robot: str) -> tuple[_Viewer, str | None]:
    """A viewer of ``robot`` (straight to the server, not relayed) that books it and sends it on
    the site's first tour, if it has one; with that tour's slug."""
    driver = _Viewer(server.port, robot, site["stream"])
    await driver.open(server.base)
    await driver.send({"type": "book"})
    tour = site["tours"][0]["slug"] if site["tours"] else None
    if tour:
        await driver.send({"type": "tour", "tour": tour})
    return driver, tour


async def _site(base: str) -> dict[str, Any]:
    import httpx

    async with httpx.AsyncClient(base_url=base, trust_env=False) as client:
        return dict((await client.get("/api/site")).json())


async def _bandwidth(server: ServedSite, seconds: float) -> dict[str, Any]:
    site = await _site(server.base)
    robot = site["robots"][0]
    port, down, relay = await _relay(server.port)
    viewer = _Viewer(port, robot, site["stream"], naive=True)  # as if the page came through the relay
    await viewer.open(server.base)
    driver, tour = await _on_tour(server, site, robot)
    start = time.monotonic()
    wire_start = down["total"]
    await asyncio.gather(viewer.run(start + seconds), driver.run(start + seconds))
    elapsed = time.monotonic() - start
    wire = down["total"] - wire_start
    people = len(viewer.decoder.scene().people)
    await viewer.close()
    await driver.close()
    relay.close()
    return {
        "seconds": elapsed,
        "wire_bytes": wire,
        "kbit_s": 8 * wire / elapsed / 1000,
        "payload_kbit_s": 8 * (viewer.binary + viewer.text) / elapsed / 1000,
        "binary_kbit_s": 8 * viewer.binary / elapsed / 1000,
        "json_kbit_s": 8 * viewer.text / elapsed / 1000,
        "naive_json_kbit_s": 8 * viewer.naive_json / elapsed / 1000,
        "frames": viewer.frames,
        "people": people,
        "tour": tour,
    }


def _children(pid: int) -> list[int]:
    """The child processes of ``pid`` (Linux /proc): the server's robots and its museum's world."""
    found = []
    for stat in Path("/proc").glob("[0-9]*/stat"):
        with suppress(OSError, IndexError, ValueError):
            if int(stat.read_text().rsplit(")", 1)[1].split()[1]) == pid:
                found.append(int(stat.parent.name))
    return found


def _viewer_worker(
    port: int, base: str, robot: str, stream: dict[str, float], n: int, ready: Any, stop: Any, results: Any
) -> None:
    """One process of viewers: ``n`` light viewers read the stream until ``stop``; their delays (and
    this process's CPU samples) go back on ``results``."""
    asyncio.run(_watch(port, base, robot, stream, n, ready, stop, results))


async def _watch(
    port: int, base: str, robot: str, stream: dict[str, float], n: int, ready: Any, stop: Any, results: Any
) -> None:
    viewers = [_Viewer(port, robot, stream) for _ in range(n)]
    readers = []
    token = await _session(base)  # one browser with n tabs: one session
    for chunk in range(0, n, 10):
        group = viewers[chunk : chunk + 10]
        await asyncio.gather(*(v.open(base, token) for v in group))
        readers += [asyncio.create_task(v.watch()) for v in group]
    ready.put(n)
    cpu = [(time.time(), time.process_time())]
    while not stop.is_set():
        await asyncio.sleep(0.25)
        cpu.append((time.time(), time.process_time()))
    for task in readers:
        task.cancel()
    await asyncio.gather(*readers, return_exceptions=True)
    results.put(([d for v in viewers for d in v.delays], cpu))
    await asyncio.gather(*(v.close() for v in viewers))


async def _drive_far(server: ServedSite, site: dict[str, Any], timeout: float = 30.0) -> None:
    """Send the robot to the exhibit farthest from where it stands (FHW: 30 m or more, a minute
    of driving, localizing and planning) and return once the stream shows it moving.

    A tour would start with a stop: the first exhibit's presentation, 8 s or more standing, and
    a standing robot sends a frame every 5 s (its refresh), so the viewers would measure little.
    """
    if not site["exhibits"]:
        return
    robot = site["robots"][0]
    driver = _Viewer(server.port, robot, site["stream"])
    await driver.open(server.base)
    await driver.send({"type": "book"})
    await driver.run(time.monotonic() + 0.5)  # the keyframe: where the robot is
    here = driver.decoder.scene().robot
    far = max(site["exhibits"], key=lambda e: math.hypot(e["x"] - here.x, e["y"] - here.y))
    await driver.send({"type": "exhibit", "exhibit": far["slug"]})
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        await driver.run(time.monotonic() + 0.2)
        robot_now = driver.decoder.scene().robot
        if math.hypot(robot_now.vx, robot_now.vy) > 0.05:
            break
    await driver.close()  # the robot goes on to the exhibit


def _cpu_between(samples: list[tuple[float, float]], start: float, end: float) -> float:
    """CPU seconds used between ``start`` and ``end`` from (wall, cpu) samples."""
    inside = [c for t, c in samples if start <= t <= end]
    return inside[-1] - inside[0] if len(inside) > 1 else math.nan


async def _viewers(
    server: ServedSite,
    n: int,
    seconds: float,
    pid: int,
    processes: int = 4,
    watched: list[ServedSite] | None = None,
) -> dict[str, Any]:
    """``n`` viewers in ``processes`` worker processes (so that the viewers' own lag is not the
    measure); each frame's delay is its arrival time minus the server's sampling time written in
    the frame (one machine: one clock; the stream's 10 ms time quantum gives +-5 ms). The viewers
    watch ``server``, or are spread over the ``watched`` servers (followers of ``server``)."""
    import multiprocessing

    site = await _site(server.base)
    robot = site["robots"][0]
    ctx = multiprocessing.get_context("spawn")
    ready, results, stop = ctx.Queue(), ctx.Queue(), ctx.Event()
    shares = [n // processes + (1 if k < n % processes else 0) for k in range(processes)]
    spread = watched or [server]
    workers = [
        ctx.Process(
            target=_viewer_worker,
            args=(at.port, at.base, robot, site["stream"], share, ready, stop, results),
            daemon=True,
        )
        for k, share in enumerate(shares)
        if share
        for at in [spread[k % len(spread)]]
    ]
    for w in workers:
        w.start()
    for _ in workers:
        await asyncio.to_thread(ready.get, True, 600)
    await _drive_far(server, site)  # the robot moving while it is watched
    await asyncio.sleep(2.0)  # keyframes and joining out of the way
    for at in spread:  # each server's own delays from here on (the followers', when they serve)
        await _staff(at, "DELETE", robot)
    robots = _children(pid)
    others = [s.process.pid for s in spread if s is not server]
    start, wall0 = time.time(), time.monotonic()
    cpu0 = [_cpu_seconds(p) for p in [pid, *robots]]
    other0 = sum(_cpu_seconds(p) for p in others)
    await asyncio.sleep(seconds)
    cpu1 = [_cpu_seconds(p) for p in [pid, *robots]]
    other1 = sum(_cpu_seconds(p) for p in others)
    wall, end = time.monotonic() - wall0, time.time()
    stop.set()
    gathered = [await asyncio.to_thread(results.get, True, 120) for _ in workers]
    for w in workers:
        w.join(30)
    delays = sorted(d for found, _ in gathered for (at, d) in found if start <= at <= end)
    viewer_cpu = sum(_cpu_between(samples, start, end) for _, samples in gathered) / (end - start)
    # the worst server's own sampled -> written delays (the viewers' side adds their reading)
    at_servers = [found for at in spread if (found := await _staff(at, "GET", robot)).get("frames")]
    if not delays:
        return {"viewers": n, "frames": 0}
    return {
        "viewers": n,
        "viewer_processes": len(workers),
        "frames": len(delays),
        "frames_per_viewer_s": len(delays) / n / (end - start),
        "p50_ms": 1000 * delays[len(delays) // 2],
        "p99_ms": 1000 * delays[min(len(delays) - 1, int(0.99 * len(delays)))],
        "max_ms": 1000 * delays[-1],
        "server_cpu": (cpu1[0] - cpu0[0]) / wall,
        "robot_cpu": sum(b - a for a, b in zip(cpu0[1:], cpu1[1:], strict=True)) / wall,
        "viewer_cpu": viewer_cpu,
        "follower_cpu": (other1 - other0) / wall,
        "followers": len(others),
        "server_p50_ms": max((found["p50_ms"] for found in at_servers), default=math.nan),
        "server_p99_ms": max((found["p99_ms"] for found in at_servers), default=math.nan),
    }


async def _staff(server: ServedSite, method: str, robot: str) -> dict[str, Any]:
    """The server's own send-delay statistics (staff API)."""
    import httpx

    try:
        async with httpx.AsyncClient(base_url=server.base, trust_env=False, timeout=120.0) as client:
            await client.post("/api/login", json={"username": "staff", "password": STAFF_PASSWORD})
            response = await client.request(method, f"/api/admin/stream/{robot}")
            return dict(response.json())
    except httpx.HTTPError as exc:  # a server too loaded to answer in two minutes
        raise typer.BadParameter(
            f"the server's staff API did not answer: {type(exc).__name__} {exc}"
        ) from None


async def _latency(server: ServedSite, trials: int) -> dict[str, Any]:
    site = await _site(server.base)
    robot = site["robots"][0]
    holder = _Viewer(server.port, robot, site["stream"])
    await holder.open(server.base)
    await holder.send({"type": "book"})
    moved: asyncio.Queue[float] = asyncio.Queue()
    state: dict[str, Any] = {"from": None}

    def on_frame(scene: Any, now: float) -> None:
        start = state["from"]
        if start is None:
            return
        x0, y0, th0 = start
        turned = abs(float(wrap_angle(scene.robot.theta - th0)))
        if (
            math.hypot(scene.robot.x - x0, scene.robot.y - y0) > 0.02
            or abs(scene.robot.vx) + abs(scene.robot.vy) > 0
            or turned > math.radians(2.0)
            or scene.robot.omega != 0.0
        ):
            moved.put_nowait(now)
            state["from"] = None

    holder.on_frame = on_frame
    reader = asyncio.create_task(holder.run(time.monotonic() + 60 * trials + 30))
    deadline = time.monotonic() + 30.0  # a slot an earlier part left may still be in its grace time
    while holder.role != "holder" and time.monotonic() < deadline:
        await asyncio.sleep(0.2)
    acks, motions = [], []
    refused: list[str] = []
    exhibits = site["exhibits"]
    for k in range(trials):
        await holder.send({"type": "stop"})
        await asyncio.sleep(2.5)  # the robot comes to rest
        while not holder.replies.empty():
            holder.replies.get_nowait()
        while not moved.empty():
            moved.get_nowait()
        scene = holder.decoder.scene()
        state["from"] = (scene.robot.x, scene.robot.y, scene.robot.theta)
        target = exhibits[k % len(exhibits)]
        sent = time.time()
        await holder.send({"type": "exhibit", "exhibit": target["slug"]})
        reply = await asyncio.wait_for(holder.replies.get(), 20)
        if reply.get("type") != "ack":  # a robot too slow to answer in time: counted, not fatal
            refused.append(str(reply.get("message", reply)))
            continue
        acks.append(time.time() - sent)
        with suppress(TimeoutError):
            motions.append(await asyncio.wait_for(moved.get(), 10) - sent)
    reader.cancel()
    with suppress(asyncio.CancelledError):
        await reader
    await holder.close()
    acks.sort()
    motions.sort()
    return {
        "trials": trials,
        "ack_p50_ms": 1000 * acks[len(acks) // 2] if acks else math.nan,
        "motion_p50_ms": 1000 * motions[len(motions) // 2] if motions else math.nan,
        "motion_max_ms": 1000 * motions[-1] if motions else math.nan,
        "moved": len(motions),
        "refused": refused,
    }


def register(bench: typer.Typer) -> None:
    @bench.command("web")
    def web(
        site: Annotated[str, typer.Option(help="site served (shipped name or file)")] = "fhw",
        seconds: Annotated[float, typer.Option(help="length of the bandwidth run")] = 60.0,
        viewers: Annotated[int, typer.Option(help="concurrent viewers")] = 200,
        viewer_seconds: Annotated[float, typer.Option(help="length of the viewers run")] = 20.0,
        trials: Annotated[int, typer.Option(help="command-to-motion trials")] = 10,
        compare: Annotated[
            bool, typer.Option(help="also measure the viewers with the robot in the server's process")
        ] = True,
        viewer_processes: Annotated[
            int, typer.Option(min=1, max=32, help="processes the viewers are spread over")
        ] = 4,
        seed: Annotated[int, typer.Option(help="seed of the simulated crowd")] = 0,
        visitors: Annotated[
            str, typer.Option("--crowd", help="visitors: a number, sparse or peak (the demo's)")
        ] = "7",
        browser: Annotated[
            bool, typer.Option(help="measure the bandwidth with the visitor page in Chromium (the wire)")
        ] = False,
        followers: Annotated[
            int,
            typer.Option(
                min=0,
                max=8,
                help="follower servers behind a Redis broker the bench starts; the viewers are "
                "spread over them (serve --broker / --follow)",
            ),
        ] = 0,
        output: Annotated[Path | None, typer.Option(help="JSON file")] = None,
    ) -> None:
        """Live-stream bandwidth, many viewers, command-to-motion latency (server in its own process)."""
        if viewers < 1:
            raise typer.BadParameter("at least one viewer", param_hint="--viewers")
        from rich.progress import Progress

        from tourbot.bench._report import BenchReport

        report = BenchReport(
            "web",
            ["measure", "value", "unit", "target", "met"],
            meta={"site": site, "seconds": seconds, "viewers": viewers, "seed": seed, "crowd": visitors,
                  "browser": browser, "followers": followers},
        )  # fmt: skip
        broker = _Broker() if followers else None
        extra = () if broker is None else ("--broker", broker.url)
        server = ServedSite(site, visitors, seed, extra=extra)
        watched: list[ServedSite] = []
        hops: list[float] = []
        try:
            with Progress(transient=True) as progress:
                task = progress.add_task("starting the server (simulated site)", total=4)
                server.wait()
                if broker is not None:
                    watched = [
                        ServedSite(site, visitors, seed, extra=("--follow", broker.url))
                        for _ in range(followers)
                    ]
                    for follower in watched:
                        follower.wait()
                progress.update(task, advance=1, description=f"bandwidth, one viewer, {seconds:.0f} s")
                measure = _browser_bandwidth if browser else _bandwidth
                bandwidth = asyncio.run(measure(server, seconds))
                progress.update(task, advance=1, description=f"{viewers} viewers, {viewer_seconds:.0f} s")
                pid = server.process.pid
                crowd = asyncio.run(
                    _viewers(server, viewers, viewer_seconds, pid, viewer_processes, watched or None)
                )
                if broker is not None:
                    from tourbot.site.default import site_path
                    from tourbot.site.model import load_site
                    from tourbot.web.fanout import channel, publish_delays

                    served = asyncio.run(_site(server.base))
                    robot = served["robots"][0]
                    name = load_site(site_path(site)).name
                    hops = sorted(publish_delays(broker.url, channel(name, robot), 5.0))
                baseline = asyncio.run(_viewers(server, 1, min(10.0, viewer_seconds), pid, 1))
                progress.update(task, advance=1, description="command-to-motion latency")
                latency = asyncio.run(_latency(server, trials))
                progress.update(task, advance=1)
        finally:
            for follower in watched:
                follower.close()
            server.close()
            if broker is not None:
                broker.close()
        in_server: dict[str, Any] = {}
        if compare:  # the same viewers against the earlier design: the robot steps in the server
            old = ServedSite(site, visitors, seed, robot_process=False)
            try:
                old.wait()
                in_server = asyncio.run(
                    _viewers(old, viewers, viewer_seconds, old.process.pid, viewer_processes)
                )
            finally:
                old.close()
        kbit = bandwidth["kbit_s"]
        report.add(
            measure=f"live stream on the wire ({'Chromium, ' if browser else ''}1 viewer, crowd {visitors})",
            value=kbit,
            unit="kbit/s",
            target=f"<= {TARGET_KBIT}",
            met=kbit <= TARGET_KBIT,
        )
        if browser:
            http = bandwidth["http_kbit_s"]
            report.add(measure="  of which plain HTTP (the page's API calls)", value=http, unit="kbit/s")
            report.add(
                measure="  payload seen by the page", value=bandwidth["page_payload_kbit_s"], unit="kbit/s"
            )
            for kind, tally in bandwidth["by_type"].items():
                kind_row = f"    {kind} ({tally['per_minute']:.0f} a minute)"
                report.add(measure=kind_row, value=tally["kbit_s"], unit="kbit/s")
            clock = bandwidth["robot_seconds_per_second"]
            report.add(measure="  robot's clock (s a wall second)", value=clock, unit="")
            report.add(measure="  tracked people shown (mean)", value=bandwidth["people_shown_mean"], unit="")
            report.add(measure="  tracked people shown (max)", value=bandwidth["people_shown_max"], unit="")
            report.add(
                measure="  shown people vs estimates, mean",
                value=100 * bandwidth["people_error_mean_m"],
                unit="cm",
            )
            report.add(
                measure="  shown people vs estimates, p95",
                value=100 * bandwidth["people_error_p95_m"],
                unit="cm",
            )
            report.add(
                measure="  tracks not shown yet (share of samples)",
                value=100 * bandwidth["people_unshown_fraction"],
                unit="%",
            )
        else:
            report.add(
                measure="  payload (binary + status JSON)", value=bandwidth["payload_kbit_s"], unit="kbit/s"
            )
            report.add(
                measure="  same states as plain JSON", value=bandwidth["naive_json_kbit_s"], unit="kbit/s"
            )
            report.add(measure="  people streamed", value=bandwidth["people"], unit="")
        report.add(measure="  paper's 240x180 video at 5 Hz", value=PAPER_VIDEO_KBIT, unit="kbit/s")
        p99 = crowd.get("p99_ms", math.nan)
        report.add(
            measure=f"update delay p50 ({viewers} viewers)", value=crowd.get("p50_ms", math.nan), unit="ms"
        )
        report.add(
            measure=f"update delay p99 ({viewers} viewers)",
            value=p99,
            unit="ms",
            target=f"<= {TARGET_P99_MS:.0f}",
            met=p99 <= TARGET_P99_MS,
        )
        report.add(
            measure=f"  at the server (the worst follower's): sampled -> sent p99 ({viewers})"
            if followers
            else f"  at the server: sampled -> sent p99 ({viewers})",
            value=crowd.get("server_p99_ms", math.nan),
            unit="ms",
        )
        report.add(measure=f"  max ({viewers} viewers)", value=crowd.get("max_ms", math.nan), unit="ms")
        report.add(
            measure=f"server CPU, web process ({viewers} viewers)",
            value=100 * crowd.get("server_cpu", math.nan),
            unit="% of a core",
        )
        report.add(
            measure="server CPU, web process (1 viewer)",
            value=100 * baseline.get("server_cpu", math.nan),
            unit="% of a core",
        )
        report.add(
            measure="robot + world processes CPU (simulator, MCL, navigator; crowd)",
            value=100 * crowd.get("robot_cpu", math.nan),
            unit="% of a core",
        )
        report.add(
            measure=f"viewers' CPU ({crowd.get('viewer_processes', 0)} processes)",
            value=100 * crowd.get("viewer_cpu", math.nan),
            unit="% of a core",
        )
        report.add(measure="update delay p99 (1 viewer)", value=baseline.get("p99_ms", math.nan), unit="ms")
        if watched:
            report.add(
                measure=f"follower servers' CPU ({len(watched)} processes)",
                value=100 * crowd.get("follower_cpu", math.nan),
                unit="% of a core",
            )
            report.add(
                measure="  broker hop, published -> received p50 / p99",
                value=f"{1000 * hops[len(hops) // 2]:.1f} / {1000 * hops[int(0.99 * (len(hops) - 1))]:.1f}"
                if hops
                else "-",
                unit="ms",
            )
        if in_server:
            report.add(
                measure=f"  robot in the server's process: p50 / p99 ({viewers})",
                value=f"{in_server.get('p50_ms', math.nan):.0f} / {in_server.get('p99_ms', math.nan):.0f}",
                unit="ms",
            )
            report.add(
                measure="  robot in the server's process: server CPU",
                value=100 * in_server.get("server_cpu", math.nan),
                unit="% of a core",
            )
        report.add(measure="command acknowledged p50", value=latency["ack_p50_ms"], unit="ms")
        report.add(measure="  commands refused (of the trials)", value=len(latency["refused"]), unit="")
        report.add(measure="command to motion seen p50", value=latency["motion_p50_ms"], unit="ms")
        report.add(measure="command to motion seen max", value=latency["motion_max_ms"], unit="ms")
        report.meta.update(
            bandwidth=bandwidth,
            viewers_run=crowd,
            baseline_run=baseline,
            latency=latency,
            in_server=in_server,
            broker_hop_ms=[1000 * h for h in hops],
        )
        if watched:
            report.notes.append(
                f"the {viewers} viewers watch {len(watched)} follower servers (serve --follow) of the "
                "server that runs the robot (serve --broker) through a Redis broker; their delay is "
                "counted from the follower's sampling, which adds the broker hop and up to one 5 Hz "
                "period of waiting for the follower's next tick"
            )
        report.notes.append(
            "server = `tourbot serve` child process (web server) with the simulated robot in its own "
            "process; the viewers run in their own worker processes on the same 2 cores; a delay is a "
            "frame's arrival minus the server's sampling time written in it (+-5 ms: 10 ms time quantum)"
        )
        if latency["refused"]:
            report.notes.append(f"commands refused in the latency trials: {latency['refused'][0]}")
        if kbit > TARGET_KBIT:
            report.notes.append(f"MISSED: bandwidth {kbit:.2f} kbit/s > {TARGET_KBIT} kbit/s")
        if not p99 <= TARGET_P99_MS:
            report.notes.append(
                f"MISSED: p99 delay {p99:.0f} ms > {TARGET_P99_MS:.0f} ms with {viewers} viewers"
            )
        report.finish(output)
