"""The shipped default site: the FHW museum (Foundation of the Hellenic World, Athens).

Its map was built from the real FHW log (``tourbot.maps.reference.build_reference_map``) and is
shipped as package data under ``tourbot/sites/fhw/`` so a fresh machine needs no robot logs.
"""

from __future__ import annotations

from pathlib import Path

from tourbot.site.model import Site, SiteError, load_site

__all__ = ["SITES_DIR", "default_site", "default_site_path", "site_path"]

SITES_DIR = Path(__file__).resolve().parent.parent / "sites"


def site_path(name_or_path: str | Path) -> Path:
    """A shipped site by name (``fhw``) or a path to a site file or folder."""
    p = Path(name_or_path)
    if p.exists():
        return p / "site.yaml" if p.is_dir() else p
    shipped = SITES_DIR / str(name_or_path) / "site.yaml"
    if shipped.exists():
        return shipped
    names = sorted(d.name for d in SITES_DIR.iterdir() if (d / "site.yaml").exists())
    raise SiteError(f"no site file or shipped site named {str(name_or_path)!r} (shipped: {', '.join(names)})")


def default_site_path() -> Path:
    return SITES_DIR / "fhw" / "site.yaml"


def default_site() -> Site:
    """The FHW museum site."""
    return load_site(default_site_path())
