from __future__ import annotations

import math

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from tourbot.web.face import FaceConfig, face_for, gaze, mood


def test_mood_goes_from_happy_to_neutral_to_angry_as_blocking_lasts() -> None:
    c = FaceConfig(neutral_after=3.0, angry_after=10.0)
    assert [mood(t, c) for t in (0.0, 2.9, 3.0, 9.9, 10.0, 60.0)] == [
        "happy", "happy", "neutral", "neutral", "angry", "angry",
    ]  # fmt: skip


def test_eyes_look_along_the_planned_path() -> None:
    pose = (0.0, 0.0, 0.0)
    assert gaze(pose, [(2.0, 0.0)]) == pytest.approx(0.0)
    assert gaze(pose, [(0.0, 2.0)]) == pytest.approx(math.radians(60))  # clamped to the head's range
    assert gaze(pose, [(1.0, 0.5)]) == pytest.approx(math.atan2(0.5, 1.0))
    # A path that turns right after 0.3 m: the eyes look ahead to where it goes after 1 m.
    assert gaze(pose, [(0.3, 0.0), (0.3, -2.0)]) < 0
    assert gaze(pose, []) == 0.0


@settings(deadline=None)
@given(
    st.tuples(st.floats(-50, 50), st.floats(-50, 50), st.floats(-math.pi, math.pi)),
    st.lists(st.tuples(st.floats(-50, 50), st.floats(-50, 50)), max_size=10),
    st.floats(0, 1000),
)
def test_face_is_always_valid(
    pose: tuple[float, float, float], path: list[tuple[float, float]], blocked: float
) -> None:
    face = face_for(pose, path, blocked)
    assert face.mood in ("happy", "neutral", "angry")
    assert abs(face.gaze) <= FaceConfig().max_gaze + 1e-12
