"""Geometry: mesh arrays and checks, welding and repair tables, resampling and transfer."""

from .mesh import MeshReport, Prepared, Repaired, as_arrays, check_mesh, note_repair, prepare, repair
from .sampling import KINDS, decimate, resample, transfer, warm_up

# isort: split
# the modules, as attributes of the package
from . import mesh, sampling  # noqa: E402

__all__ = ["MeshReport", "Prepared", "Repaired", "as_arrays", "check_mesh", "note_repair", "prepare", "repair", "KINDS", "decimate", "resample", "transfer", "warm_up", "mesh", "sampling"]
