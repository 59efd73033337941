"""Spectral operators: linear FEM, Cholesky factors, eigenpairs, heat kernels, exact heat flow.

Entry points: :func:`~o3dheat.spectral.spectrum.eigensolve`
(:class:`~o3dheat.spectral.spectrum.Spectrum`), :class:`~o3dheat.spectral.kernel.HeatKernel` and
:func:`~o3dheat.spectral.kernel.heat_kernel`, :func:`~o3dheat.spectral.heatflow.heat_flow` and
:class:`~o3dheat.spectral.heatflow.HeatFlow`, :func:`~o3dheat.spectral.diffusion.diffuse`,
:func:`~o3dheat.spectral.fem.stiffness_matrix` and :func:`~o3dheat.spectral.fem.mass_matrix`; the
modules, in the order of the data flow: fem -> linalg -> lanczos -> spectrum (cache) -> kernel
(variants) -> diffusion, krylov -> heatflow."""

from .cache import clear_cache, set_cache
from .diffusion import diffuse
from .fem import mass_matrix, stiffness_matrix
from .heatflow import HeatFlow, heat_flow
from .kernel import HeatKernel, heat_kernel
from .spectrum import Spectrum, eigensolve, shared_eigensolve
from .variants import VARIANTS

# isort: split
# the modules, as attributes of the package
from . import cache, diffusion, fem, heatflow, kernel, krylov, lanczos, linalg, spectrum, variants  # noqa: E402

# isort: split
import sys as _sys  # noqa: E402

from o3dheat import memory  # noqa: E402 - the memory limits, a base module since issue 35; its old name kept

_sys.modules.setdefault(__name__ + ".memory", memory)  # `import o3dheat.spectral.memory`: the same module

__all__ = ["mass_matrix", "stiffness_matrix", "Spectrum", "clear_cache", "eigensolve", "set_cache", "shared_eigensolve", "HeatKernel", "VARIANTS", "heat_kernel", "diffuse", "HeatFlow", "heat_flow", "fem", "linalg", "memory", "lanczos", "spectrum", "cache", "variants", "kernel", "diffusion", "krylov", "heatflow"]
