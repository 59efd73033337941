"""Geometry: mesh arrays and checks, the FEM's welding, repairs, resamplings, transfers, point clouds.

Entry points: :func:`as_arrays`, :func:`check_mesh` (:mod:`o3dheat.geometry.mesh`), :func:`prepare`
(:mod:`o3dheat.geometry.welding`), :func:`repair` (:mod:`o3dheat.geometry.repairs`), :func:`resample`
and the resamplings (:mod:`o3dheat.geometry.sampling`), :func:`transfer` and :func:`nearest`
(:mod:`o3dheat.geometry.interpolation`), :func:`reconstruct` (:mod:`o3dheat.geometry.points`).
"""

from .interpolation import nearest, transfer
from .mesh import MeshReport, as_arrays, check_mesh, check_points, face_areas, mesh_of, note_repair
from .points import point_arrays, reconstruct
from .repairs import Repaired, repair
from .sampling import KINDS, Resampled, anisotropic, decimate, jitter, remesh, resample, subdivide, warm_up
from .welding import Prepared, prepare

# isort: split
# the modules, as attributes of the package
from . import interpolation, mesh, points, repairs, sampling, welding  # noqa: E402

__all__ = ["MeshReport", "Prepared", "Repaired", "Resampled", "as_arrays", "check_mesh", "check_points", "face_areas",
           "mesh_of", "note_repair", "prepare", "repair", "KINDS", "anisotropic", "decimate", "jitter", "remesh",
           "resample", "subdivide", "warm_up", "transfer", "nearest", "point_arrays", "reconstruct",
           "interpolation", "mesh", "points", "repairs", "sampling", "welding"]
