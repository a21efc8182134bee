"""Exhibition sites: the object-based world model in one YAML file, and the shipped default site."""

from tourbot.site.default import default_site, default_site_path
from tourbot.site.model import (
    CeilingLight,
    Door,
    Exhibit,
    Furniture,
    InvisibleObstacle,
    MapSpec,
    Schedule,
    Site,
    SiteError,
    Tour,
    load_site,
    rasterize_polygons,
    site_from_dict,
)

__all__ = [
    "CeilingLight",
    "Door",
    "Exhibit",
    "Furniture",
    "InvisibleObstacle",
    "MapSpec",
    "Schedule",
    "Site",
    "SiteError",
    "Tour",
    "default_site",
    "default_site_path",
    "load_site",
    "rasterize_polygons",
    "site_from_dict",
]
