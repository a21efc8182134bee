"""TUM trajectories: ``timestamp x y z qx qy qz qw`` per line, the format ``evo`` reads.

A 2D pose ``(x, y, theta)`` is written with ``z = 0`` and the rotation ``theta`` about the z axis
(``qz = sin(theta / 2)``, ``qw = cos(theta / 2)``); reading gives back the yaw of any quaternion.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike, NDArray

from tourbot.io.errors import TrajectoryFormatError
from tourbot.io.output import write_text_whole

__all__ = ["read_tum", "write_tum"]


def write_tum(path: str | Path, times: ArrayLike, poses: ArrayLike) -> None:
    """Write one line per pose (in the given order): ``timestamp x y 0 0 0 qz qw``."""
    t = np.asarray(times, dtype=np.float64).reshape(-1)
    p = np.asarray(poses, dtype=np.float64).reshape(-1, 3)
    if len(t) != len(p):
        raise TrajectoryFormatError(f"{len(t)} timestamps for {len(p)} poses", path=path)
    if not (np.isfinite(t).all() and np.isfinite(p).all()):
        raise TrajectoryFormatError("a timestamp or pose is not finite (NaN or infinite)", path=path)
    lines = ["# timestamp x y z qx qy qz qw"]
    for ti, (x, y, th) in zip(t.tolist(), p.tolist(), strict=True):
        qz, qw = math.sin(th / 2.0), math.cos(th / 2.0)
        lines.append(f"{ti!r} {x!r} {y!r} 0.0 0.0 0.0 {qz!r} {qw!r}")
    write_text_whole(path, "\n".join(lines) + "\n")


def read_tum(path: str | Path) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Read a TUM trajectory: times ``(N,)`` and 2D poses ``(N, 3)`` (x, y, yaw); ``#`` comments."""
    p = Path(path)
    if not p.exists():
        raise TrajectoryFormatError("no such file", path=p)
    times: list[float] = []
    poses: list[tuple[float, float, float]] = []
    names = ("timestamp", "x", "y", "z", "qx", "qy", "qz", "qw")
    try:
        text = p.read_text()
    except UnicodeDecodeError:
        raise TrajectoryFormatError("binary data, not a TUM text file", path=p) from None
    for lineno, line in enumerate(text.splitlines(), start=1):
        fields = line.split()
        if not fields or fields[0].startswith("#"):
            continue
        if len(fields) != 8:
            raise TrajectoryFormatError(
                f"{len(fields)} fields, 8 expected (timestamp x y z qx qy qz qw)", path=p, line=lineno
            )
        values = []
        for name, tok in zip(names, fields, strict=True):
            try:
                v = float(tok)
            except ValueError:
                raise TrajectoryFormatError(
                    f"{tok!r} is not a number", path=p, line=lineno, field=name
                ) from None
            if not math.isfinite(v):
                raise TrajectoryFormatError(f"{tok!r} is not finite", path=p, line=lineno, field=name)
            values.append(v)
        ts, x, y, _, qx, qy, qz, qw = values
        if abs(qx * qx + qy * qy + qz * qz + qw * qw - 1.0) > 1e-3:
            raise TrajectoryFormatError("the quaternion is not of unit length", path=p, line=lineno)
        yaw = math.atan2(2.0 * (qw * qz + qx * qy), 1.0 - 2.0 * (qy * qy + qz * qz))
        times.append(ts)
        poses.append((x, y, yaw))
    if not times:
        raise TrajectoryFormatError("no poses in the file", path=p)
    return np.array(times), np.array(poses)
