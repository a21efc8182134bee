from __future__ import annotations

import json

from tourbot.snapshot import (
    DoorState,
    FurnitureState,
    GroundTruth,
    NavigationStatus,
    NavMode,
    PersonState,
    PoseEstimate,
    SampleSummary,
    StateSnapshot,
)


def _full_snapshot() -> StateSnapshot:
    return StateSnapshot(
        time=12.5,
        step=125,
        source="sim",
        pose=PoseEstimate(1.0, 2.0, 0.5, ((0.01, 0, 0), (0, 0.02, 0), (0, 0, 0.003))),
        samples=SampleSummary(count=5000, n_effective=1234.5, poses=((1.0, 2.0, 0.5), (1.1, 2.1, 0.4))),
        people=(PersonState(3, 4.0, 5.0, 0.5, -0.5, True),),
        doors=(DoorState("hall", 0.7, 0.5),),
        furniture=(FurnitureState("bench", 1.0, 1.0, 0.2),),
        navigation=NavigationStatus(
            mode=NavMode.BLOCKED,
            goal=(3.0, 4.0, 0.0),
            tour="highlights",
            current_exhibit="globe",
            exhibit_index=1,
            exhibits_total=4,
            visited=("entrance",),
            path=((1.0, 2.0), (3.0, 4.0)),
            blocked_time=2.5,
            total_blocked_time=7.0,
        ),
        truth=GroundTruth(pose=(1.05, 2.0, 0.49), people=(PersonState(0, 4.1, 5.0),), collisions=0),
        site="fhw",
        estimators={"people": {"tracks": 1}},
    )


def test_snapshot_round_trips_through_json() -> None:
    snap = _full_snapshot()
    data = json.loads(snap.to_json())
    assert data["navigation"]["mode"] == "blocked"
    assert StateSnapshot.from_dict(data) == snap


def test_empty_snapshot_round_trips() -> None:
    snap = StateSnapshot(time=0.0, step=0, source="log")
    assert StateSnapshot.from_dict(json.loads(snap.to_json())) == snap


def test_position_error_and_progress() -> None:
    snap = _full_snapshot()
    assert snap.position_error is not None
    assert abs(snap.position_error - 0.05) < 1e-9
    assert snap.navigation.progress == 0.25
    assert StateSnapshot(time=0.0, step=0, source="x").position_error is None
