"""Geometry: mesh arrays and checks, the FEM's welding, repairs, resamplings, transfers, point clouds.

Entry points: :func:`~o3dheat.geometry.mesh.as_arrays`, :func:`~o3dheat.geometry.mesh.check_mesh`
(:mod:`o3dheat.geometry.mesh`), :func:`~o3dheat.geometry.welding.prepare`
(:mod:`o3dheat.geometry.welding`), :func:`~o3dheat.geometry.repairs.repair`
(:mod:`o3dheat.geometry.repairs`), :func:`~o3dheat.geometry.sampling.resample` and the resamplings
(:mod:`o3dheat.geometry.sampling`), :func:`~o3dheat.geometry.interpolation.transfer` and
:func:`~o3dheat.geometry.interpolation.nearest` (:mod:`o3dheat.geometry.interpolation`),
:func:`~o3dheat.geometry.points.reconstruct` (:mod:`o3dheat.geometry.points`),
:func:`~o3dheat.geometry.up.up_axis` (:mod:`o3dheat.geometry.up`: which axis is up)."""

from .interpolation import TransferMap, nearest, transfer, transfer_map
from .mesh import MeshReport, as_arrays, check_mesh, check_points, face_areas, mesh_of, note_repair
from .points import point_arrays, reconstruct
from .repairs import Repaired, repair
from .sampling import KINDS, Resampled, anisotropic, decimate, jitter, remesh, resample, subdivide, warm_up
from .up import height, up_axis
from .welding import Prepared, prepare

# isort: split
# the modules, as attributes of the package
from . import interpolation, mesh, points, repairs, sampling, up, welding  # noqa: E402

__all__ = ["MeshReport", "Prepared", "Repaired", "Resampled", "as_arrays", "check_mesh", "check_points", "face_areas",
           "mesh_of", "note_repair", "prepare", "repair", "KINDS", "anisotropic", "decimate", "jitter", "remesh",
           "resample", "subdivide", "warm_up", "transfer", "transfer_map", "TransferMap", "nearest", "point_arrays", "reconstruct",
           "interpolation", "mesh", "points", "repairs", "sampling", "welding", "up", "up_axis", "height"]
