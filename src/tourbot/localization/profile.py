"""The configuration of every localizer, one section each, from defaults or a profile file.

``tourbot config show [--config FILE]`` prints it; ``--config FILE`` on ``localize``, ``simulate``,
``demo``, ``serve`` and ``bench`` loads it (:mod:`tourbot.configuration`). Site profiles ship beside
the sites (``src/tourbot/sites/fhw/localization.yaml``).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from tourbot.configuration import load_yaml, to_yaml
from tourbot.localization.grid_markov import GridMarkovConfig
from tourbot.localization.mcl.config import MCLConfig

__all__ = ["FHW_PROFILE", "LocalizationProfile"]

#: the profile tuned on the FHW museum log
SITE_PROFILE = "localization.yaml"  # a site folder's localization profile, beside its site.yaml
FHW_PROFILE = Path(__file__).resolve().parents[1] / "sites" / "fhw" / SITE_PROFILE


@dataclass(frozen=True)
class LocalizationProfile:
    """``mcl``: Monte Carlo localization; ``grid``: grid Markov localization."""

    mcl: MCLConfig = field(default_factory=MCLConfig)
    grid: GridMarkovConfig = field(default_factory=GridMarkovConfig)

    @classmethod
    def load(cls, path: Path | None) -> LocalizationProfile:
        """The defaults with the file ``path`` (None: the defaults alone)."""
        if path is None:
            return cls()
        sections = load_yaml(path, {"mcl": MCLConfig, "grid": GridMarkovConfig})
        return cls(mcl=sections["mcl"], grid=sections["grid"])

    @classmethod
    def for_site(cls, site_file: Path, path: Path | None) -> tuple[LocalizationProfile, Path | None]:
        """The profile a robot on the site at ``site_file`` runs with, and the file it came from:
        ``path`` when given, else the site's own ``localization.yaml`` beside its site file (its
        values tuned on that building), else the papers' defaults (None)."""
        if path is None:
            shipped = site_file.parent / SITE_PROFILE
            path = shipped if shipped.is_file() else None
        return cls.load(path), path

    def to_yaml(self) -> str:
        """The whole effective configuration as YAML."""
        return to_yaml({"mcl": self.mcl, "grid": self.grid})
