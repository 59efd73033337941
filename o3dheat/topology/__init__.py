"""Topology of scalar fields: PL critical points, persistence, level sets, tracks, approximation.

Modules, in the order of the data:

* :mod:`~o3dheat.topology.surface`: :class:`~o3dheat.topology.surface.Surface`
* :mod:`~o3dheat.topology.critical`: :func:`~o3dheat.topology.critical.critical_points`
* :mod:`~o3dheat.topology.persistence`: :func:`~o3dheat.topology.persistence.persistence` (the
  package's attribute ``persistence`` is the function, not the module)
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
