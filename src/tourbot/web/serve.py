"""Serving a site: the simulated (or real) robots, the database, the app, uvicorn.

``tourbot serve`` and ``tourbot demo`` both call :func:`build_site_app` then
:func:`run`.
"""

from __future__ import annotations

import errno
import secrets
import socket
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING

from fastapi import FastAPI
from rich.console import Console

from tourbot.errors import TourbotError
from tourbot.localization.mcl.config import MCLConfig
from tourbot.web.app import WebConfig, create_app
from tourbot.web.db import Database, default_url, open_database
from tourbot.web.guard import GuardConfig
from tourbot.web.link import RobotLink
from tourbot.web.sitedata import import_site

if TYPE_CHECKING:
    import uvicorn

    from tourbot.sim.camera import ForwardCameraSim
    from tourbot.sim.fleet import FleetPoses
    from tourbot.sim.simulator import Simulator
    from tourbot.sim.world import MuseumWorld
    from tourbot.web.world_process import WorldProcess

__all__ = [
    "ServeSettings",
    "SimulatedMuseum",
    "SimulatedRobotFactory",
    "SimulatedWorldFactory",
    "build_site_app",
    "run",
    "simulated_links",
    "simulated_museum",
]


@dataclass(frozen=True)
class ServeSettings:
    """What ``tourbot serve`` is told: site, database, robots, simulation, network."""

    site: str = "fhw"
    database: str | None = None
    robots: int = 1
    crowd: str = "sparse"
    seed: int = 0
    mcl: MCLConfig = field(default_factory=MCLConfig)  # the robots' localization
    host: str = "127.0.0.1"
    port: int = 8000
    slot_minutes: float = 10.0
    staff_password: str | None = None
    speech_dir: Path = Path(".tourbot-speech")
    speedup: float = 1.0  # the simulated robots run this many times faster than real time
    fresh_staff_password: bool = False  # a new generated password at each start (the demo's)
    robot_process: bool = True  # each simulated robot in its own process (see web.process_link)
    certfile: Path | None = None  # TLS: serve HTTPS (and Secure cookies) with this certificate
    keyfile: Path | None = None
    trusted_proxies: tuple[str, ...] = ()  # addresses whose X-Forwarded-For/-Proto are believed
    onboard_token: str | None = None  # pairs the robot's screen (default: a new one at each start)
    foxglove: int | None = None  # a live Foxglove server per robot on this port (+1, +2 for the others)
    broker: str | None = None  # publish the robots' views on this Redis broker (web.fanout)
    follow: str | None = None  # show the robots a controlling server publishes on this broker
    cameras: tuple[str, ...] = ()  # the cameras the simulated robots carry and use (SimulatedRobotFactory)


def _robot_names(n: int) -> list[str]:
    # The TOURBOT and WebFAIR robots' names (Lefkos at FHW, Albert at Hannover, Rhino in Bonn).
    names = ["lefkos", "albert", "rhino", "minerva"]
    return [names[i] if i < len(names) else f"robot{i + 1}" for i in range(n)]


#: The high-resolution picture: the forward camera's images this many times as wide and high.
PHOTO_SCALE = 2.0


@dataclass
class SimulatedPhoto:
    """A high-resolution picture of a simulated robot's forward camera, rendered on request from
    where the robot stands now, with the visitors, doors and furniture as they are (JPEG)."""

    simulator: Simulator
    camera: ForwardCameraSim
    quality: int = 90

    @classmethod
    def of(cls, simulator: Simulator, seed: int) -> SimulatedPhoto:
        from tourbot.sim.camera import ForwardCameraSim
        from tourbot.vision.camera import ForwardCamera

        camera = ForwardCameraSim(simulator.site, ForwardCamera().scaled(PHOTO_SCALE), seed=seed)
        return cls(simulator, camera)

    def __call__(self) -> bytes:
        import cv2

        sim = self.simulator
        self.camera.set_world(sim.world)
        frame = self.camera.frame(sim.time, sim.robot.pose, sim.people_positions())
        ok, jpeg = cv2.imencode(".jpg", frame.image, [cv2.IMWRITE_JPEG_QUALITY, self.quality])
        if not ok:
            raise TourbotError("the camera's picture could not be encoded")
        return bytes(jpeg.tobytes())


@dataclass(frozen=True)
class SimulatedRobotFactory:
    """Builds one simulated robot (site, crowd, MCL, people tracker, navigator) behind a
    :class:`RuntimeLink`.

    Picklable, so that the robot can be built inside its own process (:class:`ProcessLink`).
    ``speedup`` shortens the link's period (for a robot stepped by the server's thread).
    """

    site: str
    crowd: str | int
    seed: int
    mcl: MCLConfig
    speedup: float = 1.0
    start: tuple[float, float, float] | None = None  # None: the site's start pose
    foxglove: int | None = None  # serve the robot's channels live to Foxglove on this port
    foxglove_host: str = "127.0.0.1"  # ... on this address (the web server's)
    # several robots in one museum: (shared-memory name, robots, this robot's index), sim.fleet
    fleet: tuple[str, int, int] | None = None
    # the cameras the robot carries and uses (app.simulated.CAMERAS): "ceiling" (fused into MCL),
    # "forward" (vision obstacles)
    cameras: tuple[str, ...] = ()

    def at(self, pose: tuple[float, float, float]) -> SimulatedRobotFactory:
        """The same robot standing at ``pose`` (its last estimate, when its process restarts)."""
        return replace(self, start=pose)

    def __call__(self) -> RobotLink:
        from tourbot.app.simulated import SimulationSettings, simulated_runtime
        from tourbot.site.default import site_path
        from tourbot.site.model import load_site
        from tourbot.web.runtime_link import RuntimeLink

        site = load_site(site_path(self.site))
        # the robot estimates its doors and furniture: the pages draw them, MCL and the navigator use them
        sim_settings = SimulationSettings(
            crowd=self.crowd,
            seed=self.seed,
            mcl=self.mcl,
            objects=True,
            people=True,  # the pages show the people the robot perceives: its tracker on its laser
        ).carrying(self.cameras)
        fleet = None
        start = self.start
        if self.fleet is not None:
            from tourbot.sim.fleet import FleetPoses

            name, size, index = self.fleet
            fleet = (FleetPoses(size, name=name), index)
            if start is None and site.exhibits:  # robot k starts at exhibit k, not on another robot
                start = site.exhibits[index % len(site.exhibits)].viewing_pose
        robot = simulated_runtime(site, sim_settings, start=start, record=False, fleet=fleet)
        if self.foxglove is not None:
            from tourbot.app.ros2_publishing import RunPublisher
            from tourbot.io.foxglove_live import FoxgloveLive

            # open for the robot's life: its process ends, or the server stops, and so does this
            live = FoxgloveLive(
                self.foxglove, host=self.foxglove_host, name=f"tourbot {self.site}"
            ).__enter__()
            robot.runtime.add_sink(RunPublisher(live, robot.runtime))
        period = float(robot.simulator.dt) / self.speedup
        return RuntimeLink(
            robot.runtime,
            period=period,
            site_tours=frozenset(t.name for t in site.tours),
            camera=SimulatedPhoto.of(robot.simulator, self.seed),
        )


@dataclass(frozen=True)
class SimulatedWorldFactory:
    """Builds the museum's world (its one crowd, :class:`tourbot.sim.world.MuseumWorld`) on the
    fleet's shared memory ``fleet`` (its name and number of robots); picklable, for its process."""

    site: str
    crowd: str | int
    seed: int
    fleet: tuple[str, int]

    def __call__(self) -> MuseumWorld:
        from tourbot.app.simulated import crowd_config
        from tourbot.sim.fleet import FleetPoses
        from tourbot.sim.simulator import SimConfig
        from tourbot.sim.world import MuseumWorld
        from tourbot.site.default import site_path
        from tourbot.site.model import load_site

        config = crowd_config(self.crowd)
        if config is None:
            raise TourbotError("the museum's world: an empty museum has no crowd to step")
        name, size = self.fleet
        return MuseumWorld(
            load_site(site_path(self.site)),
            config,
            FleetPoses(size, name=name),
            seed=self.seed,
            dt=SimConfig().dt,
        )


@dataclass
class SimulatedMuseum:
    """The simulated robots of ``tourbot serve`` and the world they share: ``fleet`` (their poses
    and the visitors, shared memory), ``world`` (the process stepping the one crowd; None for an
    empty museum, or one robot stepped by the server's thread, whose simulator keeps its crowd)."""

    links: dict[str, RobotLink]
    fleet: FleetPoses | None = None
    world: WorldProcess | None = None

    def close(self) -> None:
        """Stop the robots' processes and the world's; free the shared memory (idempotent)."""
        for link in self.links.values():
            close = getattr(link, "close", None)
            if callable(close):
                close()
        if self.world is not None:
            self.world.close()
            self.world = None
        if self.fleet is not None:
            self.fleet.close()
            self.fleet = None


def simulated_links(settings: ServeSettings) -> dict[str, RobotLink]:
    """The robots of :func:`simulated_museum`; their world is closed when the server's process ends."""
    import atexit

    museum = simulated_museum(settings)
    atexit.register(museum.close)
    return museum.links


def simulated_museum(settings: ServeSettings) -> SimulatedMuseum:
    """One simulated robot per name (seeds ``seed``, ``seed + 1``, ...), each in its own process
    when ``settings.robot_process`` (else stepped by the server's thread). The robots share one
    world (:mod:`tourbot.sim.fleet`): each other's bodies, and one crowd of visitors stepped by the
    museum's world in a process of its own (:mod:`tourbot.web.world_process`) with every robot's
    pose: the visitors gather at, follow and step aside for each robot, and a robot's process that
    dies and is restarted leaves them walking where they were."""
    from tourbot.app.simulated import crowd_config
    from tourbot.sim.fleet import FleetPoses
    from tourbot.web.process_link import ProcessLink
    from tourbot.web.world_process import WorldProcess

    links: dict[str, RobotLink] = {}
    crowded = crowd_config(settings.crowd) is not None
    shared = settings.robots >= 2 or (settings.robot_process and crowded)
    museum = SimulatedMuseum(links, FleetPoses(settings.robots) if shared else None)
    fleet = museum.fleet
    if fleet is not None and crowded:
        world = SimulatedWorldFactory(
            settings.site, settings.crowd, settings.seed, (fleet.name, settings.robots)
        )
        museum.world = WorldProcess(world, speedup=settings.speedup)
    for i, name in enumerate(_robot_names(settings.robots)):
        seed = settings.seed + i
        fox = None if settings.foxglove is None else settings.foxglove + i
        share = None if fleet is None else (fleet.name, settings.robots, i)
        if settings.robot_process:
            factory = SimulatedRobotFactory(
                settings.site,
                settings.crowd,
                seed,
                settings.mcl,
                foxglove=fox,
                foxglove_host=settings.host,
                fleet=share,
                cameras=settings.cameras,
            )
            links[name] = ProcessLink(factory, speedup=settings.speedup, name=name)
        else:
            factory = SimulatedRobotFactory(
                settings.site,
                settings.crowd,
                seed,
                settings.mcl,
                settings.speedup,
                foxglove=fox,
                foxglove_host=settings.host,
                fleet=share,
                cameras=settings.cameras,
            )
            links[name] = factory()
    try:
        for link in links.values():
            if isinstance(link, ProcessLink):
                link.wait_ready()
        if museum.world is not None:
            museum.world.wait_ready()
    except TourbotError:
        museum.close()
        raise
    return museum


def _roster(site: str) -> str:
    return f"tourbot:{site}:robots"


def published_links(settings: ServeSettings, site: str, links: dict[str, RobotLink]) -> dict[str, RobotLink]:
    """``links``, each publishing its views on ``settings.broker``; the roster (robot names and
    this server's address, where they are controlled) is left on the broker for followers."""
    import json

    from tourbot.web.fanout import PublishingLink, channel, connect

    assert settings.broker is not None
    client = connect(settings.broker)
    control = addresses(settings.host, settings.port, tls=settings.certfile is not None)["visitor page"]
    client.set(_roster(site), json.dumps({"robots": list(links), "control": control}))
    return {name: PublishingLink(link, client, channel(site, name)) for name, link in links.items()}


def followed_links(settings: ServeSettings, site: str) -> dict[str, RobotLink]:
    """The robots of ``site`` that a controlling server publishes on ``settings.follow``."""
    import json

    from tourbot.web.fanout import BrokerError, FollowerLink, channel, connect

    assert settings.follow is not None
    client = connect(settings.follow)
    roster = client.get(_roster(site))
    if roster is None:
        raise BrokerError(
            f"no robots of site {site!r} on the broker {settings.follow}: start the controlling "
            f"server first (tourbot serve --site {site} --broker {settings.follow})"
        )
    try:
        data = json.loads(roster)
        names, control = [str(n) for n in data["robots"]], str(data["control"])
    except (ValueError, KeyError, TypeError):
        raise BrokerError(f"{settings.follow}: the key {_roster(site)} is not a tourbot roster") from None
    links: dict[str, RobotLink] = {}
    for name in names:
        link = FollowerLink(client, channel(site, name), controlled_at=control)
        link.wait_ready()
        links[name] = link
    return links


def build_site_app(
    settings: ServeSettings,
    links: dict[str, RobotLink] | None = None,
    console: Console | None = None,
) -> tuple[FastAPI, Database]:
    """The server of ``settings.site``; its exhibits and tours are imported on first start."""
    from tourbot.site.default import site_path
    from tourbot.site.model import load_site

    console = console or Console()
    site = load_site(site_path(settings.site))
    db = open_database(settings.database or default_url(site.name), site=site.name)
    if not db.exhibits():
        exhibits, tours = import_site(site, db)
        console.print(
            f"imported {exhibits} exhibits and {tours} tours from the site file into {db.url}", soft_wrap=True
        )
    if settings.staff_password:
        db.set_staff("staff", settings.staff_password)
    elif settings.fresh_staff_password or not db.has_staff():
        password = secrets.token_urlsafe(9)
        db.set_staff("staff", password)
        console.print(
            f"staff login created: user [bold]staff[/], password [bold]{password}[/]", soft_wrap=True
        )
    if settings.broker and settings.follow:
        raise TourbotError("a server either publishes its robots (--broker) or follows another's (--follow)")
    if links is None:
        links = followed_links(settings, site.name) if settings.follow else simulated_links(settings)
    if settings.broker:
        links = published_links(settings, site.name, links)
    base = WebConfig()
    onboard_token = settings.onboard_token or secrets.token_urlsafe(18)
    config = WebConfig(
        site_name=site.description.split(":")[0] if site.description else site.name,
        slots=replace(base.slots, slot_length=settings.slot_minutes * 60.0),
        speech_dir=settings.speech_dir,
        guard=GuardConfig(),
        onboard_token=onboard_token,
        secure_cookies=settings.certfile is not None,
        drive_robots=not settings.follow,
    )
    app = create_app(links, db, site.grid, config)
    app.state.pairing = f"/onboard/pair?token={onboard_token}"
    return app, db


def listening_socket(host: str, port: int, fallback: bool) -> socket.socket:
    """A socket bound to ``host:port``; when the port is taken, a free one if ``fallback``, else an
    error that says so in one line."""
    family = socket.AF_INET6 if ":" in host else socket.AF_INET
    sock = socket.socket(family, socket.SOCK_STREAM)
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
    try:
        sock.bind((host, port))
    except OSError as exc:
        if not fallback or exc.errno != errno.EADDRINUSE:
            sock.close()
            raise TourbotError(
                f"cannot listen on {host}:{port}: {exc.strerror}; choose another --port"
            ) from None
        sock.bind((host, 0))
    sock.set_inheritable(True)
    return sock


def addresses(host: str, port: int, *, tls: bool = False, pairing: str = "/onboard") -> dict[str, str]:
    """The pages of a server listening on ``host:port``, by role (``pairing``: the on-board
    screen's pairing address, secret, to open once on the robot's own screen)."""
    shown = f"[{host}]" if ":" in host else host
    base = f"{'https' if tls else 'http'}://{shown}:{port}"
    return {
        "visitor page": f"{base}/",
        "on-board screen": f"{base}{pairing}",
        "staff (admin)": f"{base}/admin",
    }


def uvicorn_config(
    app: FastAPI,
    *,
    certfile: Path | None = None,
    keyfile: Path | None = None,
    trusted_proxies: tuple[str, ...] = (),
) -> uvicorn.Config:
    """The server's settings: forwarded headers believed only from ``trusted_proxies`` (by default
    from nobody, so a client cannot choose its own address for the rate limits), TLS when a
    certificate is given. WebSocket frames larger than 64 kB are refused by the protocol layer
    before any parsing."""
    import uvicorn

    from tourbot.web.shared_frames import SharedFrameProtocol

    if (certfile is None) != (keyfile is None):
        raise TourbotError("TLS needs both --certfile and --keyfile")
    for path in (certfile, keyfile):
        if path is not None and not path.is_file():
            raise TourbotError(f"{path}: no such file")
    return uvicorn.Config(
        app,
        log_level="warning",
        ws=SharedFrameProtocol,  # the stream's frames built once, written to every viewer as they are
        ws_max_size=65536,
        ws_per_message_deflate=True,  # the JSON texts; the stream's binary frames go uncompressed
        timeout_graceful_shutdown=5,
        proxy_headers=bool(trusted_proxies),
        forwarded_allow_ips=list(trusted_proxies) or None,
        ssl_certfile=None if certfile is None else str(certfile),
        ssl_keyfile=None if keyfile is None else str(keyfile),
    )


def run(
    app: FastAPI,
    host: str,
    port: int,
    console: Console | None = None,
    *,
    fallback: bool = False,
    certfile: Path | None = None,
    keyfile: Path | None = None,
    trusted_proxies: tuple[str, ...] = (),
) -> None:
    """Serve until interrupted (Ctrl-C stops it cleanly); prints the addresses once it listens.

    With ``fallback`` a taken port is replaced by a free one (said in one line); without, a taken
    port is a :class:`TourbotError`.
    """
    import uvicorn

    out = console or Console()
    config = uvicorn_config(app, certfile=certfile, keyfile=keyfile, trusted_proxies=trusted_proxies)
    sock = listening_socket(host, port, fallback)
    bound = int(sock.getsockname()[1])
    if port and bound != port:
        out.print(f"port {port} is in use: serving on port {bound} instead")

    class _Server(uvicorn.Server):
        async def startup(self, sockets: list[socket.socket] | None = None) -> None:
            await super().startup(sockets)
            if self.started:
                pairing = str(getattr(app.state, "pairing", "/onboard"))
                for role, url in addresses(host, bound, tls=certfile is not None, pairing=pairing).items():
                    out.print(f"{role + ':':17} [bold]{url}[/]", soft_wrap=True)
                out.print("serving; press Ctrl-C to stop", highlight=False)

    try:
        _Server(config).run(sockets=[sock])
    except KeyboardInterrupt:  # uvicorn re-raises the Ctrl-C it handled, once it has shut down
        pass
    finally:
        sock.close()
    out.print("stopped")
