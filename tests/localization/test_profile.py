"""A robot on a site runs with the profile the site ships, unless it is given another one."""

from __future__ import annotations

from pathlib import Path

from tourbot.localization.profile import FHW_PROFILE, LocalizationProfile
from tourbot.site.default import site_path


def test_a_site_that_ships_a_profile_runs_with_it() -> None:
    profile, applied = LocalizationProfile.for_site(site_path("fhw"), None)
    assert applied == FHW_PROFILE
    assert profile == LocalizationProfile.load(FHW_PROFILE)
    assert profile != LocalizationProfile()  # the FHW values differ from the papers'


def test_a_site_without_a_profile_runs_with_the_papers_values() -> None:
    profile, applied = LocalizationProfile.for_site(site_path("domus"), None)
    assert applied is None
    assert profile == LocalizationProfile()


def test_a_given_profile_wins_over_the_sites(tmp_path: Path) -> None:
    given = tmp_path / "mine.yaml"
    given.write_text("mcl:\n  sampling:\n    max_samples: 4321\n")
    profile, applied = LocalizationProfile.for_site(site_path("fhw"), given)
    assert applied == given
    assert profile.mcl.sampling.max_samples == 4321
    assert profile.mcl != LocalizationProfile.load(FHW_PROFILE).mcl
