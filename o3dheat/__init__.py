"""o3dheat: multi-scale heat-kernel analysis for Open3D meshes: :func:`eigensolve`, :class:`HeatKernel`,
:func:`heat_flow`, :func:`critical_points`, :func:`track_critical_points`, :func:`view`, ``filters.apply``,
``io.read_mesh``.

Implements the weighted linear-FEM heat kernel of Patanè & Falcidieno, "Multi-Scale Feature
Spaces for Shape Processing and Analysis" (SMI 2010). See the README and the documentation site (scripts/docs.sh) for a tour.
"""

from .errors import MeshError, SolverError
from .geometry import MeshReport, Repaired, as_arrays, check_mesh, repair
from .pipelines import robustness_study
from .spectral import (
    VARIANTS,
    HeatFlow,
    HeatKernel,
    Spectrum,
    diffuse,
    eigensolve,
    heat_flow,
    heat_kernel,
    mass_matrix,
    stiffness_matrix,
)
from .topology import (
    CriticalPoints,
    PersistenceDiagram,
    ScaleSpace,
    Tracks,
    critical_points,
    feature_driven,
    level_sets,
    persistence,
    scale_space,
    simplify_critical_points,
    track_critical_points,
)
from .visualization import View, view

# isort: split
# the stages as attributes of the package, and the modules users reach by their short names
# (o3dheat.filters.apply, o3dheat.batch.run, o3dheat.plot.field, ...)
from . import geometry, io, pipelines, spectral, topology, visualization  # noqa: E402, F401
from .geometry import sampling  # noqa: E402, F401
from .pipelines import batch, cluster, filters, study  # noqa: E402, F401
from .spectral import fem, heatflow, kernel, krylov  # noqa: E402, F401
from .topology import approximation  # noqa: E402, F401
from .visualization import figures, plot  # noqa: E402, F401


def _short_names():
    """``import o3dheat.plot`` (and the other short names above) imports the module at its one home
    (``o3dheat.visualization.plot``): the same module object, registered under both names, so that
    scripts written against the earlier flat layout keep working."""
    import sys

    for name in ("sampling", "batch", "cluster", "filters", "study", "fem", "heatflow", "kernel", "krylov",
                 "approximation", "figures", "plot"):
        sys.modules.setdefault(f"{__name__}.{name}", globals()[name])


_short_names()

try:  # one place for the version: pyproject.toml, through the installed package's metadata
    from importlib.metadata import PackageNotFoundError
    from importlib.metadata import version as _version

    __version__ = _version("o3dheat")
except PackageNotFoundError:  # a source tree that was never installed
    __version__ = "0+unknown"

__all__ = [
    "as_arrays", "check_mesh", "MeshReport", "repair", "Repaired",
    "stiffness_matrix", "mass_matrix",
    "eigensolve", "Spectrum",
    "HeatKernel", "heat_kernel", "VARIANTS",
    "heat_flow", "HeatFlow",
    "diffuse",
    "critical_points", "CriticalPoints", "persistence", "PersistenceDiagram",
    "simplify_critical_points", "level_sets",
    "feature_driven", "scale_space", "ScaleSpace",
    "robustness_study",
    "MeshError", "SolverError",
    "__version__", "Tracks", "track_critical_points",
    "view", "View",
]
