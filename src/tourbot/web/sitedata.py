"""From a site file (:mod:`tourbot.site`) to the web database: exhibits and tours, in minutes.

Burgard et al. (section 7.1) needed under two days to install at a new site, most of it for the
map and the multimedia content. Here the map comes from the site file (built from a log) and the
exhibits and tours are imported once, then edited on the admin page or with ``tourbot site``.
"""

from __future__ import annotations

from typing import Any

from tourbot.web.db import Database

__all__ = ["import_site", "title"]


def title(slug: str) -> str:
    """A display name for a slug: ``minoan-fresco`` -> ``Minoan fresco``."""
    words = slug.replace("_", " ").replace("-", " ").strip()
    return words[:1].upper() + words[1:]


def import_site(site: Any, db: Database, *, replace: bool = False) -> tuple[int, int]:
    """Copy ``site``'s exhibits (at their viewing poses) and tours into ``db``.

    Existing exhibits and tours of the same name are kept unless ``replace`` (their web content
    may have been edited since). Returns the numbers of exhibits and tours written.
    """
    known = {e.slug for e in db.exhibits()}
    tours = {t.slug for t in db.tours()}
    written = [0, 0]
    for exhibit in site.exhibits:
        if exhibit.name in known and not replace:
            continue
        x, y, theta = exhibit.viewing_pose
        db.save_exhibit(
            exhibit.name, title(exhibit.name), x=x, y=y, theta=theta, text=exhibit.text, summary=exhibit.text
        )
        written[0] += 1
    for tour in site.tours:
        if tour.name in tours and not replace:
            continue
        db.save_tour(tour.name, title(tour.name), tour.exhibits, tour.description)
        written[1] += 1
    return written[0], written[1]
