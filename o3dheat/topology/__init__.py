"""Topology of scalar fields: PL critical points, persistence, level sets, tracks, approximation."""

from .approximation import ScaleSpace, feature_driven, scale_space
from .critical import (
    MAXIMUM,
    MINIMUM,
    REGULAR,
    SADDLE,
    CriticalPoints,
    compiled_in_this_process,
    critical_points,
    warm_up,
)
from .levelsets import level_sets
from .persistence import PersistenceDiagram, persistence, simplify_critical_points
from .surface import Surface
from .tracking import Tracks, track_critical_points

# isort: split
# the modules, as attributes of the package (but the module persistence: the name is the function's,
# o3dheat.topology.persistence(mesh, f); import the module as `from o3dheat.topology.persistence import ...`)
from . import approximation, critical, levelsets, surface, tracking  # noqa: E402

__all__ = [
    "REGULAR", "MINIMUM", "SADDLE", "MAXIMUM", "CriticalPoints", "PersistenceDiagram", "Surface",
    "compiled_in_this_process", "critical_points", "level_sets", "persistence", "simplify_critical_points",
    "warm_up", "Tracks", "track_critical_points", "ScaleSpace", "feature_driven", "scale_space",
    "surface", "critical", "levelsets", "tracking", "approximation"]
