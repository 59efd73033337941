"""The ``.npz`` codec (numpy's zip of arrays): :func:`read_npz`, :func:`write_npz`.

Notes
-----
Layout: ``positions`` and ``indices`` (meshes), and every other attribute ``a`` as ``vertex_a``
with its shape and dtype (read without pickles).
"""

from __future__ import annotations

import numpy as np

from o3dheat.errors import MeshError

from ._geometry import new_geometry
from .files import atomic_write

__all__ = ["read_npz", "write_npz"]


def write_npz(path, attrs, F, binary):
    """Write positions, faces (or None) and attributes to ``path`` atomically (``binary`` unused)."""
    arrays = {"positions": attrs["positions"]}
    if F is not None:
        arrays["indices"] = F
    arrays.update({f"vertex_{k}": v for k, v in attrs.items() if k != "positions"})
    for k, v in arrays.items():
        if v.dtype.hasobject:
            raise MeshError(f"cannot write {path}: {k!r} holds Python objects")
    atomic_write(path, lambda fh: np.savez(fh, **arrays))


def read_npz(path):
    """A ``.npz`` written by :func:`write_npz`: a tensor mesh, or a point cloud without ``indices``."""
    import open3d as o3d

    try:
        with np.load(path, allow_pickle=False) as z:
            data = {k: z[k] for k in z.files}
    except Exception as e:
        raise MeshError(f"{path}: not a readable NPZ file ({type(e).__name__}: {e})") from e
    if "positions" not in data:
        raise MeshError(f"{path}: no 'positions' array (not written by o3dheat?)")
    V = data.pop("positions")
    if V.ndim != 2 or V.shape[1] != 3 or not (np.issubdtype(V.dtype, np.floating) or np.issubdtype(V.dtype, np.integer)):
        raise MeshError(f"{path}: 'positions' must be an (n, 3) array of real numbers, got shape {V.shape} and "
                        f"dtype {V.dtype}")
    n = len(V)
    if "indices" in data:
        F = data.pop("indices")
        if (F.ndim != 2 or F.shape[1] != 3 or not np.issubdtype(F.dtype, np.integer)
                or (F.size and (F.min() < 0 or F.max() >= n))):
            raise MeshError(f"{path}: 'indices' is not a valid (m, 3) array of vertex indices")
    else:
        F = None
    geo, attrs = new_geometry(F)
    attrs["positions"] = o3d.core.Tensor(V)
    for key, arr in data.items():
        name = key[len("vertex_"):] if key.startswith("vertex_") else key
        if name == "positions" or arr.ndim == 0:
            raise MeshError(f"{path}: {key!r} is not a vertex attribute o3dheat writes (corrupt or crafted file)")
        if len(arr) != n:
            raise MeshError(f"{path}: {key!r} has {len(arr)} rows for {n} vertices")
        if not (np.issubdtype(arr.dtype, np.integer) or np.issubdtype(arr.dtype, np.floating)
                or arr.dtype == bool):
            raise MeshError(f"{path}: {key!r} has dtype {arr.dtype}: a vertex attribute is numbers (integers, "
                            "floats or booleans)")
        attrs[name] = o3d.core.Tensor(np.ascontiguousarray(arr))
    return geo
