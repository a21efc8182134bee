"""The tour executor: exhibit after exhibit, stop at the viewing pose, dwell, go on; report progress.

Burgard et al. (tele-presence paper, "tours" and the museum robots' tour mode): a tour is an
ordered list of exhibits; at each the robot stops at a viewing pose and presents the exhibit for a
while. Exhibits that cannot be reached (no path, or blocked too long) are skipped and reported.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from tourbot.site.model import Exhibit, Site

__all__ = ["TourExecutor", "TourState"]


@dataclass
class TourState:
    """Progress of one tour."""

    name: str
    exhibits: list[Exhibit]
    index: int = 0
    dwelling: bool = False
    dwell_left: float = 0.0
    visited: list[str] = field(default_factory=list)
    skipped: list[str] = field(default_factory=list)

    @property
    def current(self) -> Exhibit | None:
        return self.exhibits[self.index] if self.index < len(self.exhibits) else None

    @property
    def done(self) -> bool:
        return self.index >= len(self.exhibits)


class TourExecutor:
    """Walks through a site's tour; the navigator drives, this decides where and for how long."""

    def __init__(self, site: Site, dwell_scale: float = 1.0) -> None:
        self.site = site
        self.dwell_scale = dwell_scale
        self.state: TourState | None = None

    def start(self, tour: str) -> Exhibit:
        t = self.site.tour(tour)  # raises SiteError naming the tours
        self.state = TourState(t.name, [self.site.exhibit(n) for n in t.exhibits])
        exhibit = self.state.current
        assert exhibit is not None  # a tour has at least one exhibit (validated)
        return exhibit

    def cancel(self) -> None:
        self.state = None

    def arrived(self) -> None:
        """The robot reached the current exhibit's viewing pose: start presenting it."""
        s = self.state
        if s is None or s.current is None:
            return
        s.dwelling = True
        s.dwell_left = s.current.dwell * self.dwell_scale

    def skip(self) -> Exhibit | None:
        """Give up the current exhibit; the next one, if any."""
        s = self.state
        if s is None or s.current is None:
            return None
        s.skipped.append(s.current.name)
        s.index += 1
        s.dwelling = False
        return s.current

    def dwell(self, dt: float) -> Exhibit | bool | None:
        """Present for ``dt`` seconds; the next exhibit when done (None at the tour's end), or
        True while still presenting."""
        s = self.state
        if s is None or s.current is None:
            return None
        s.dwell_left -= dt
        if s.dwell_left > 0:
            return True
        s.visited.append(s.current.name)
        s.index += 1
        s.dwelling = False
        return s.current
