"""The figures tourbot is judged by, as pure functions of estimates and references (no I/O).

- :mod:`tourbot.metrics.localization`: position and heading errors, failures (more than 45 cm
  off) and recovery from kidnapping as Fox et al. (1998) define them, with one censoring rule;
- :mod:`tourbot.metrics.relative`: relative pose error of a mapping run (Kummerle et al. 2009);
- :mod:`tourbot.metrics.closures`: loop closures against the reference, and against the scans
  where the two disagree;
- :mod:`tourbot.metrics.mot`: CLEAR-MOT and IDF1 of a people tracker.

The CLI and every benchmark use these; none computes its own.
"""

from tourbot.metrics.localization import (
    FAILURE_DISTANCE,
    RECOVERED_FOR,
    Recovery,
    converged_index,
    failure_rate,
    mean_ci,
    pose_errors,
    recovery,
    settle_index,
)
from tourbot.metrics.mot import Frame, clear_mot
from tourbot.metrics.relative import RelativeError, relative_pose_error

__all__ = [
    "FAILURE_DISTANCE",
    "RECOVERED_FOR",
    "Frame",
    "Recovery",
    "RelativeError",
    "clear_mot",
    "converged_index",
    "failure_rate",
    "mean_ci",
    "pose_errors",
    "recovery",
    "relative_pose_error",
    "settle_index",
]
