"""The on-board face (Burgard et al., section 6.2): mood from how long visitors block the way,
eyes towards where the robot is heading.

"If the path of the robot is not obstructed by the on-site visitors, the robot appears happy. In
the opposite case, the robot's 'mood' changes progressively in time." Three expressions: happy,
neutral, angry. "The head of the robot is controlled so that it looks towards the direction of
intended motion."
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

from tourbot.geometry import wrap_angle

__all__ = ["Face", "FaceConfig", "face_for", "gaze", "mood"]


@dataclass(frozen=True)
class FaceConfig:
    """After ``neutral_after`` seconds blocked the robot stops smiling; after ``angry_after`` it
    frowns. The paper gives no figures; these keep a short wait friendly. ``look_ahead`` is how far
    along the planned path the eyes look (m); ``max_gaze`` how far the head turns (rad)."""

    neutral_after: float = 3.0
    angry_after: float = 10.0
    look_ahead: float = 1.0
    max_gaze: float = math.radians(60.0)


@dataclass(frozen=True)
class Face:
    mood: str
    gaze: float

    def as_dict(self) -> dict[str, object]:
        return {"mood": self.mood, "gaze": round(self.gaze, 2)}


def mood(blocked_time: float, config: FaceConfig | None = None) -> str:
    c = config or FaceConfig()
    if blocked_time < c.neutral_after:
        return "happy"
    return "neutral" if blocked_time < c.angry_after else "angry"


def gaze(
    pose: tuple[float, float, float], path: Sequence[tuple[float, float]], config: FaceConfig | None = None
) -> float:
    """Head angle relative to the body (rad, left positive) towards the path ``look_ahead`` ahead."""
    c = config or FaceConfig()
    x, y, theta = pose
    target = None
    travelled = 0.0
    px, py = x, y
    for qx, qy in path:
        travelled += math.hypot(qx - px, qy - py)
        target = (qx, qy)
        px, py = qx, qy
        if travelled >= c.look_ahead:
            break
    if target is None or math.hypot(target[0] - x, target[1] - y) < 1e-6:
        return 0.0
    angle = float(wrap_angle(math.atan2(target[1] - y, target[0] - x) - theta))
    return max(-c.max_gaze, min(c.max_gaze, angle))


def face_for(
    pose: tuple[float, float, float],
    path: Sequence[tuple[float, float]],
    blocked_time: float,
    config: FaceConfig | None = None,
) -> Face:
    return Face(mood(blocked_time, config), gaze(pose, path, config))
