"""People tracking: leg features, the sample-based JPDA filter (SJPDAF), the occlusion map and the
static-object filter (Burgard et al., Sec. 4)."""

from tourbot.people.estimator import PeopleEstimator
from tourbot.people.legs import LegConfig, LegFeatures, PersonFeatures, detect_legs, group_legs
from tourbot.people.motion import WalkingModel
from tourbot.people.occlusion import OcclusionConfig, occlusion_map
from tourbot.people.sjpdaf import PeopleTracker, SJPDAFConfig, Track
from tourbot.people.static_filter import StaticConfig, StaticFilter

__all__ = [
    "LegConfig",
    "LegFeatures",
    "OcclusionConfig",
    "PeopleEstimator",
    "PeopleTracker",
    "PersonFeatures",
    "SJPDAFConfig",
    "StaticConfig",
    "StaticFilter",
    "Track",
    "WalkingModel",
    "detect_legs",
    "group_legs",
    "occlusion_map",
]
