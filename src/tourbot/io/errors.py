"""Errors of the log, bag, map and trajectory readers and writers."""

from __future__ import annotations

from tourbot.errors import InputError

__all__ = ["BagError", "LogFormatError", "MapFormatError", "TrajectoryFormatError"]


class LogFormatError(InputError):
    """A robot log that cannot be read: says the file, the line and what was wrong."""


class BagError(InputError):
    """A ROS bag that cannot be read or has none of the requested topics."""


class MapFormatError(InputError):
    """A ROS map_server map (YAML + image) that cannot be read."""


class TrajectoryFormatError(InputError):
    """A TUM trajectory file that cannot be read."""
