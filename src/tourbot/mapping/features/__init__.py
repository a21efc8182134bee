"""Feature-based mapping (Burgard et al. Sec. 2.2): line segments and corners, string-search
association, EM with a Rauch-Tung-Striebel smoother, multiple hypotheses started at corners."""

from tourbot.mapping.features.extraction import (
    Corner,
    ExtractionParams,
    Segment,
    extract_corners,
    extract_segments,
)
from tourbot.mapping.features.mapper import (
    FeatureMap,
    FeatureMapper,
    FeatureMappingParams,
    LoopClosure,
    MapLine,
)

__all__ = [
    "Corner",
    "ExtractionParams",
    "FeatureMap",
    "FeatureMapper",
    "FeatureMappingParams",
    "LoopClosure",
    "MapLine",
    "Segment",
    "extract_corners",
    "extract_segments",
]
