"""Monte Carlo localization with the entropy and novelty filters of Fox et al. (1998).

Dellaert, Fox, Burgard & Thrun 1999, "Monte Carlo localization for mobile robots"; Fox, Burgard,
Thrun & Cremers 1998, "Position estimation for mobile robots in dynamic environments" (the
filters); Thrun, Burgard & Fox, *Probabilistic Robotics* (2005) for the motion and sensor models,
augmented MCL and low-variance resampling; Fox 2003 for KLD-sampling. Modules:

- :mod:`~tourbot.localization.mcl.localizer`: the filter, :class:`MonteCarloLocalization`;
- :mod:`~tourbot.localization.mcl.config`: its typed configuration, :class:`MCLConfig`;
- :mod:`~tourbot.localization.mcl.sensor`: the sensor model and the :class:`PoseLikelihood` seam;
- :mod:`~tourbot.localization.mcl.recovery`: recovery and its state;
- :mod:`~tourbot.localization.mcl.search`: global localization and sensor resetting's search;
- :mod:`~tourbot.localization.mcl.clustering` and :mod:`~tourbot.localization.mcl.kld`.
"""

from tourbot.localization.errors import LocalizationError
from tourbot.localization.estimate import LocalizationEstimate
from tourbot.localization.mcl.clustering import (
    best_cluster_estimate,
    best_cluster_estimate_reference,
    cluster_bins,
    cluster_bins_reference,
)
from tourbot.localization.mcl.config import (
    GlobalConfig,
    MCLConfig,
    RecoveryConfig,
    SamplingConfig,
    SearchConfig,
    SensorConfig,
)
from tourbot.localization.mcl.kld import kld_bounds, kld_sample_count
from tourbot.localization.mcl.localizer import MonteCarloLocalization
from tourbot.localization.mcl.recovery import Recovery, RecoveryState
from tourbot.localization.mcl.sensor import LaserSensorModel, PoseLikelihood
from tourbot.sampling import systematic_resample as low_variance_resample
from tourbot.sampling import systematic_resample_reference as low_variance_resample_reference

__all__ = [
    "GlobalConfig",
    "LaserSensorModel",
    "LocalizationError",
    "LocalizationEstimate",
    "MCLConfig",
    "MonteCarloLocalization",
    "PoseLikelihood",
    "Recovery",
    "RecoveryConfig",
    "RecoveryState",
    "SamplingConfig",
    "SearchConfig",
    "SensorConfig",
    "best_cluster_estimate",
    "best_cluster_estimate_reference",
    "cluster_bins",
    "cluster_bins_reference",
    "kld_bounds",
    "kld_sample_count",
    "low_variance_resample",
    "low_variance_resample_reference",
]
