"""o3dheat: multi-scale heat-kernel analysis for Open3D meshes.

Implements the weighted linear-FEM heat kernel of Patanè & Falcidieno, "Multi-Scale Feature
Spaces for Shape Processing and Analysis" (SMI 2010). See the README and the documentation site (scripts/docs.sh) for a tour.
"""

from .approximation import ScaleSpace, feature_driven, scale_space
from .diffusion import diffuse
from .errors import MeshError, SolverError
from .fem import mass_matrix, stiffness_matrix
from .heatflow import HeatFlow, heat_flow
from .kernel import VARIANTS, HeatKernel, heat_kernel
from .mesh import MeshReport, Repaired, as_arrays, check_mesh, repair
from .spectrum import Spectrum, eigensolve
from .study import robustness_study
from .topology import (
    CriticalPoints,
    PersistenceDiagram,
    critical_points,
    level_sets,
    persistence,
    simplify_critical_points,
)
from .tracking import Tracks, track_critical_points

# isort: split
# (after the names above: the submodules as attributes of the package)
from . import (  # noqa: E402, F401  (o3dheat.filters.apply, o3dheat.batch.run, ...)
    approximation,
    batch,
    cluster,
    fem,
    figures,
    filters,
    heatflow,
    io,
    krylov,
    plot,
    sampling,
    study,
    topology,
)

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
]
