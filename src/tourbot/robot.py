"""The robot's description: the limits of its differential-drive base.

Shared by the navigator (which plans and drives within them) and the simulator (which moves a
simulated base within them), so it sits in the bottom layer and neither imports the other.
Defaults are those of a museum tour-guide robot of the TOURBOT/RHINO family (an RWI B21 base,
about 52 cm across, driven at walking pace among visitors; Burgard et al., "Experiences with an
interactive museum tour-guide robot", and the tele-presence paper's robots Albert and Rhino).
"""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["DiffDriveConfig"]


@dataclass(frozen=True)
class DiffDriveConfig:
    """Limits of the base. ``radius`` is the footprint used for collisions and planning."""

    radius: float = 0.3
    max_speed: float = 0.6  # m/s: tours go at walking pace among visitors
    max_reverse: float = 0.1  # m/s backwards
    max_turn_rate: float = 1.2  # rad/s
    max_accel: float = 0.6  # m/s^2
    max_turn_accel: float = 2.0  # rad/s^2
    laser_height: float = 0.4  # m: a laser at about 40 cm sees legs, not low tables or glass cases

    def __post_init__(self) -> None:
        for name in ("radius", "max_speed", "max_turn_rate", "max_accel", "max_turn_accel"):
            if not getattr(self, name) > 0:
                raise ValueError(f"DiffDriveConfig.{name} must be positive")
