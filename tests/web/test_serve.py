"""``tourbot serve`` on the shipped FHW site drives the real simulator runtime."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from fastapi.testclient import TestClient

from tests.web.test_app import connect, new_session, role_is, wait_for
from tourbot.localization.profile import FHW_PROFILE, LocalizationProfile
from tourbot.web.serve import ServeSettings, build_site_app


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
