"""Open3D geometries and the attribute arrays the codecs read and write: :func:`attributes`,
:func:`new_geometry`, :func:`soup` (shared by :mod:`o3dheat.io.meshes` and the format modules)."""

from __future__ import annotations

import numpy as np

from o3dheat.errors import MeshError

__all__ = ["RESERVED", "attributes", "new_geometry", "soup"]


#: vertex attributes with a meaning of their own (Open3D's names), stored apart
RESERVED = {"positions", "normals", "colors"}


def attributes(geometry, need_faces=True):
    """({name: (n, ...) array}, faces (m, 3) or None) of an Open3D mesh or point cloud."""
    import open3d as o3d

    if isinstance(geometry, o3d.geometry.TriangleMesh):
        geometry = o3d.t.geometry.TriangleMesh.from_legacy(geometry)
    elif isinstance(geometry, o3d.geometry.PointCloud):
        geometry = o3d.t.geometry.PointCloud.from_legacy(geometry)
    if isinstance(geometry, o3d.t.geometry.TriangleMesh):
        attrs = {key: geometry.vertex[key].numpy() for key in geometry.vertex}
        if "indices" not in geometry.triangle:
            raise MeshError("the mesh has no triangles")
        F = geometry.triangle.indices.numpy()
    elif isinstance(geometry, o3d.t.geometry.PointCloud) and not need_faces:
        attrs = {key: geometry.point[key].numpy() for key in geometry.point}
        F = None
    else:
        raise MeshError(f"expected an Open3D TriangleMesh{'' if need_faces else ' or PointCloud'}, "
                        f"got {type(geometry).__name__}")
    if "positions" not in attrs:
        raise MeshError("the geometry has no vertex positions")
    n = len(attrs["positions"])
    for key, arr in attrs.items():
        if len(arr) != n:
            raise MeshError(f"vertex attribute {key!r} has {len(arr)} rows, the geometry {n} vertices")
    return attrs, F


def new_geometry(F):
    """An empty tensor mesh with faces F, or a point cloud when F is None, and its vertex map."""
    import open3d as o3d

    if F is None:
        geo = o3d.t.geometry.PointCloud()
        return geo, geo.point
    geo = o3d.t.geometry.TriangleMesh()
    geo.triangle.indices = o3d.core.Tensor(F)
    return geo, geo.vertex


def soup(corners):
    """A TriangleMesh whose every triangle has its own three vertices (what STL stores; o3dheat
    welds them where it computes: :func:`o3dheat.geometry.welding.prepare`)."""
    import open3d as o3d

    V = np.ascontiguousarray(corners, dtype=np.float64).reshape(-1, 3)
    F = np.arange(len(V), dtype=np.int64).reshape(-1, 3)
    return o3d.t.geometry.TriangleMesh(o3d.core.Tensor(V), o3d.core.Tensor(F))
