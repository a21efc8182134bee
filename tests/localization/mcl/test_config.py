"""The MCL configuration: the papers' defaults, the FHW profile, and what is refused."""

from __future__ import annotations

import math

import pytest

from tourbot.configuration import ConfigError, from_mapping
from tourbot.localization.beam_filters import BeamFilter
from tourbot.localization.errors import LocalizationError
from tourbot.localization.mcl import MCLConfig, RecoveryConfig, SamplingConfig, SensorConfig
from tourbot.localization.profile import FHW_PROFILE, LocalizationProfile
from tourbot.maps.likelihood_field import LikelihoodFieldParams


def test_defaults_are_the_papers_and_the_data() -> None:
    cfg = MCLConfig()
    assert (cfg.sampling.min_samples, cfg.sampling.max_samples) == (500, 2000)  # Nav2 AMCL
    assert (cfg.sampling.kld_epsilon, cfg.sampling.kld_quantile) == (0.05, 0.99)  # Fox 2003
    assert cfg.sensor.beam_filter == BeamFilter.NOVELTY  # Fox et al. 1998's recommendation
    assert cfg.sensor.filters.theta == 0.99
    # learned from the data as PR Sec. 6.3 and Fox et al. 1998 (Eq. 5) do: bench sensor-model
    assert cfg.sensor.field == LikelihoodFieldParams(sigma_hit=0.05, distance="surface")
    assert cfg.sensor.novelty_sigma == 0.05
    assert cfg.sensor.likelihood_exponent == 1.0  # the product (PR Eq. 6.2): see the docstring
    assert (cfg.recovery.alpha_slow, cfg.recovery.alpha_fast, cfg.recovery.ratio) == (0.001, 0.1, 1.0)
    assert cfg.recovery.verify_period is None
    assert cfg.sensor.entropy_cell == (0.15, math.radians(2.0))


def test_the_fhw_profile_holds_the_site_tuned_values() -> None:
    fhw = LocalizationProfile.load(FHW_PROFILE).mcl
    assert fhw.sampling.max_samples == 5000
    assert fhw.sensor.likelihood_exponent == 0.2
    assert (fhw.sensor.field.sigma_hit, fhw.sensor.field.distance) == (0.1, "surface")
    assert (fhw.recovery.alpha_slow, fhw.recovery.alpha_fast, fhw.recovery.ratio) == (0.01, 1.0, 0.5)
    assert fhw.global_ == MCLConfig().global_
    assert LocalizationProfile.load(None) == LocalizationProfile()


def test_sample_budgets_and_filters() -> None:
    cfg = MCLConfig().with_samples(300)
    assert (cfg.sampling.min_samples, cfg.sampling.max_samples) == (300, 300)
    assert MCLConfig().with_samples(1000).sampling.min_samples == 500
    assert MCLConfig().with_samples(1000, fixed=True).sampling.min_samples == 1000
    assert MCLConfig().with_filter(BeamFilter.ENTROPY).sensor.beam_filter == BeamFilter.ENTROPY


def test_nonsense_is_refused() -> None:
    with pytest.raises(LocalizationError, match="min_samples"):
        SamplingConfig(min_samples=10, max_samples=5)
    with pytest.raises(LocalizationError, match="likelihood_exponent"):
        SensorConfig(likelihood_exponent=0.0)
    with pytest.raises(LocalizationError, match="novelty_sigma"):
        SensorConfig(novelty_sigma=-0.01)
    with pytest.raises(LocalizationError, match="max_injection"):
        RecoveryConfig(max_injection=1.5)
    with pytest.raises(ConfigError, match=r"mcl\.sensor\.field\.distance: must be one of centre, surface"):
        from_mapping(MCLConfig, {"sensor": {"field": {"distance": "middle"}}}, "mcl")
