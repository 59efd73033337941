"""o3dheat: multi-scale heat-kernel analysis for Open3D meshes.

Implements the weighted linear-FEM heat kernel of Patanè & Falcidieno, "Multi-Scale Feature
Spaces for Shape Processing and Analysis" (SMI 2010). See the README for a tour.
"""

from .diffusion import diffuse
from .errors import MeshError, SolverError
from .fem import mass_matrix, stiffness_matrix
from .kernel import HeatKernel
from .mesh import MeshReport, as_arrays, check_mesh
from .spectrum import Spectrum, eigensolve

__version__ = "0.1.0"

__all__ = [
    "as_arrays", "check_mesh", "MeshReport",
    "stiffness_matrix", "mass_matrix",
    "eigensolve", "Spectrum",
    "HeatKernel",
    "diffuse",
    "MeshError", "SolverError",
    "__version__",
]
