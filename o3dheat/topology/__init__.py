"""Topology of scalar fields: PL critical points, persistence, level sets, tracks, approximation.

Modules, in the order of the data:

* :mod:`~o3dheat.topology.surface`: :class:`~o3dheat.topology.surface.Surface`
* :mod:`~o3dheat.topology.critical`: :func:`~o3dheat.topology.critical.critical_points`
* :mod:`~o3dheat.topology.diagrams`: :func:`~o3dheat.topology.diagrams.persistence`,
  :class:`~o3dheat.topology.diagrams.PersistenceDiagram`, :func:`~o3dheat.topology.diagrams.simplify_critical_points`
* :mod:`~o3dheat.topology.levelsets`: :func:`~o3dheat.topology.levelsets.level_sets`
* :mod:`~o3dheat.topology.tracking`: :func:`~o3dheat.topology.tracking.track_critical_points`
* :mod:`~o3dheat.topology.approximation`: :func:`~o3dheat.topology.approximation.scale_space`,
  :func:`~o3dheat.topology.approximation.feature_driven`
"""

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
from .diagrams import PersistenceDiagram, persistence, simplify_critical_points
from .levelsets import level_sets
from .surface import Surface
from .tracking import Tracks, track_critical_points

# isort: split
# the modules, as attributes of the package
from . import approximation, critical, diagrams, levelsets, surface, tracking  # noqa: E402

__all__ = [
    "REGULAR", "MINIMUM", "SADDLE", "MAXIMUM", "CriticalPoints", "PersistenceDiagram", "Surface",
    "compiled_in_this_process", "critical_points", "level_sets", "persistence", "simplify_critical_points",
    "warm_up", "Tracks", "track_critical_points", "ScaleSpace", "feature_driven", "scale_space",
    "surface", "critical", "diagrams", "levelsets", "tracking", "approximation"]
