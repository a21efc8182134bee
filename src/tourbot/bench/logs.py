"""The real robot logs the localization benchmarks read (``bench localization``, ``bench
sensor-model``), by name, and their reference maps, cached."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

from tourbot.errors import TourbotError

if TYPE_CHECKING:
    from tourbot.maps.grid import OccupancyGrid
    from tourbot.records import RobotLog

__all__ = ["LOGS", "chosen_logs", "reference_map"]

# the name of each log and its file in the shared data folder's ``carmen/``
LOGS = {
    "fhw": "fhw-corrected.log.gz",
    "intel": "intel-corrected.log.gz",
    "aces": "aces-corrected.log.gz",
    "freiburg-079": "freiburg-079-corrected.log.gz",
}


def chosen_logs(logs: str) -> dict[str, Path]:
    """The logs named in ``logs`` (comma separated names of :data:`LOGS`), each with its file, in
    the order given; a one-line error when the shared data folder is absent or a name unknown."""
    from tourbot.data import data_dir

    root = data_dir()
    if root is None:
        raise TourbotError("the real robot logs (../shared/data) are needed for this benchmark")
    names = [n.strip() for n in logs.split(",") if n.strip()]
    for n in names:
        if n not in LOGS:
            raise TourbotError(f"unknown log {n!r}; choose from {', '.join(LOGS)}")
    return {n: root / "carmen" / LOGS[n] for n in names}


def reference_map(log: RobotLog, name: str, cache: Path) -> OccupancyGrid:
    """The 5 cm reference map of ``log`` (:func:`tourbot.maps.reference.build_reference_map`),
    read back from ``cache/NAME-map.yaml`` once it was written there (and always read from the
    file, so a fresh map and a cached one are the same)."""
    from tourbot.io.mapserver import read_map, write_map
    from tourbot.maps.reference import build_reference_map

    path = cache / f"{name}-map.yaml"
    if path.exists():
        return read_map(path)
    grid = build_reference_map(log, 0.05)
    write_map(grid, path)
    return read_map(path)
