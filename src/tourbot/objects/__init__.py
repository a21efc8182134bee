"""State estimation of doors and furniture from the moving robot (Schulz and Burgard 2001)."""

from tourbot.objects.estimator import (
    ObjectBelief,
    ObjectEstimate,
    ObjectEstimatorConfig,
    ObjectStateEstimator,
    Observation,
    Quality,
)

__all__ = [
    "ObjectBelief",
    "ObjectEstimate",
    "ObjectEstimatorConfig",
    "ObjectStateEstimator",
    "Observation",
    "Quality",
]
