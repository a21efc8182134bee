"""The runtime: one event loop from a source to estimators, a state snapshot, the navigator and sinks."""

from tourbot.runtime.interfaces import (
    DrivableSource,
    Estimator,
    EstimatorOutput,
    Localizer,
    Navigator,
    PoseBelief,
    ScanShare,
    Sink,
    Source,
)
from tourbot.runtime.loop import Runtime, RuntimeConfig, RuntimeControlError
from tourbot.runtime.snapshot import (
    DoorState,
    FurnitureState,
    GroundTruth,
    NavigationStatus,
    NavMode,
    PersonState,
    PoseEstimate,
    SampleSummary,
    StateSnapshot,
)

__all__ = [
    "DoorState",
    "DrivableSource",
    "Estimator",
    "EstimatorOutput",
    "FurnitureState",
    "GroundTruth",
    "Localizer",
    "NavMode",
    "NavigationStatus",
    "Navigator",
    "PersonState",
    "PoseBelief",
    "PoseEstimate",
    "Runtime",
    "RuntimeConfig",
    "RuntimeControlError",
    "SampleSummary",
    "ScanShare",
    "Sink",
    "Source",
    "StateSnapshot",
]
