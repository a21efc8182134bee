"""Configurations for the MCL tests: the FHW profile (the values the scenes were written for)."""

from __future__ import annotations

from typing import Any

from tourbot.configuration import from_mapping
from tourbot.localization.mcl import MCLConfig
from tourbot.localization.profile import FHW_PROFILE, LocalizationProfile


def tuned(samples: int, min_samples: int, **groups: dict[str, Any]) -> MCLConfig:
    """The FHW profile with ``samples`` / ``min_samples`` and the fields of ``groups`` changed
    (``recovery={"max_injection": 0.0}``)."""
    base = LocalizationProfile.load(FHW_PROFILE).mcl
    data: dict[str, Any] = {"sampling": {"max_samples": samples, "min_samples": min_samples}}
    for name, fields in groups.items():
        data.setdefault(name, {}).update(fields)
    return from_mapping(MCLConfig, data, "mcl", base)
