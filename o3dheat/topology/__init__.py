"""Topology of scalar fields: PL critical points, persistence, level sets, tracks, approximation."""

from .approximation import ScaleSpace, feature_driven, scale_space
from .critical import (
    MAXIMUM,
    MINIMUM,
    REGULAR,
    SADDLE,
    CriticalPoints,
    PersistenceDiagram,
    Surface,
    compiled_in_this_process,
    critical_points,
    level_sets,
    persistence,
    simplify_critical_points,
    warm_up,
)
from .tracking import Tracks, track_critical_points

# isort: split
# the modules, as attributes of the package
from . import approximation, critical, tracking  # noqa: E402

__all__ = [
    "REGULAR", "MINIMUM", "SADDLE", "MAXIMUM","REGULAR", "MINIMUM", "SADDLE", "MAXIMUM", "CriticalPoints", "PersistenceDiagram", "Surface", "compiled_in_this_process", "critical_points", "level_sets", "persistence", "simplify_critical_points", "warm_up", "Tracks", "track_critical_points", "ScaleSpace", "feature_driven", "scale_space", "critical", "tracking", "approximation"]
