"""Point clouds: their arrays (:func:`point_arrays`) and a surface through them (:func:`reconstruct`)."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from o3dheat.errors import MeshError

from .mesh import as_arrays, check_points
from .repairs import repair

if TYPE_CHECKING:  # Open3D is imported when a cloud is read (1.5 s): for annotations only
    import open3d as o3d

__all__ = ["point_arrays", "reconstruct"]


def point_arrays(cloud: o3d.t.geometry.PointCloud | o3d.geometry.PointCloud)\
        -> tuple[np.ndarray, np.ndarray | None]:
    """Positions (n, 3) float64 and normals (n, 3) or None of an Open3D point cloud (tensor or legacy).

    Examples
    --------
    >>> import numpy as np, open3d as o3d
    >>> from o3dheat.geometry.points import point_arrays
    >>> pc = o3d.t.geometry.PointCloud(o3d.core.Tensor(np.eye(3, dtype=np.float32)))
    >>> P, N = point_arrays(pc)
    >>> P.dtype, P.shape, N is None
    (dtype('float64'), (3, 3), True)
    """
    import open3d as o3d

    if isinstance(cloud, o3d.t.geometry.PointCloud):
        if "positions" not in cloud.point or len(cloud.point.positions) == 0:
            raise MeshError("the point cloud is empty")
        P = cloud.point.positions.numpy().astype(np.float64)
        N = cloud.point.normals.numpy().astype(np.float64) if "normals" in cloud.point else None
    elif isinstance(cloud, o3d.geometry.PointCloud):
        if not cloud.has_points():
            raise MeshError("the point cloud is empty")
        P = np.asarray(cloud.points, dtype=np.float64)
        N = np.asarray(cloud.normals, dtype=np.float64) if cloud.has_normals() else None
    else:
        raise MeshError(f"expected an Open3D point cloud, got {type(cloud).__name__}")
    if not np.all(np.isfinite(P)):
        raise MeshError("the point cloud has NaN or infinite coordinates")
    return P, N


def reconstruct(cloud: o3d.t.geometry.PointCloud | o3d.geometry.PointCloud, method: str = "poisson", depth: int = 8,
                neighbours: int = 30, trim: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """A triangle mesh through a point cloud.

    Parameters
    ----------
    cloud : o3d.t.geometry.PointCloud or o3d.geometry.PointCloud
        Normals are estimated (``neighbours`` nearest points) and oriented consistently when
        missing.
    method : {"poisson", "ball_pivoting"}
        Screened Poisson (watertight, new vertices) or ball pivoting (the points themselves as
        vertices, radii from the mean spacing).
    depth : int
        Octree depth of the Poisson reconstruction.
    neighbours : int
        Neighbours for the normal estimation and orientation.
    trim : float
        Poisson only: remove this fraction of the vertices with the lowest sample density (the
        surface Poisson invents far from the points, for open scans); 0 keeps a closed surface.

    Returns
    -------
    V : (r, 3) float64 ndarray
    F : (m, 3) int64 ndarray

    Examples
    --------
    >>> import numpy as np, open3d as o3d
    >>> from o3dheat.geometry.points import reconstruct
    >>> P = np.random.default_rng(0).standard_normal((3000, 3)); P /= np.linalg.norm(P, axis=1)[:, None]
    >>> V, F = reconstruct(o3d.t.geometry.PointCloud(o3d.core.Tensor(P)))
    >>> bool(abs(np.linalg.norm(V, axis=1).mean() - 1) < 0.02)
    True
    """
    import open3d as o3d

    if method not in ("poisson", "ball_pivoting"):
        raise MeshError(f"unknown reconstruction {method!r}: use 'poisson' or 'ball_pivoting'")
    P, N = point_arrays(cloud)
    check_points(P, planar=False, min_points=10, what="the point cloud to reconstruct")
    pcd = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(P))
    if N is None or not np.all(np.isfinite(N)):
        pcd.estimate_normals(o3d.geometry.KDTreeSearchParamKNN(neighbours))
        pcd.orient_normals_consistent_tangent_plane(neighbours)
        # orient outwards on average (a closed surface around its centroid)
        Nn = np.asarray(pcd.normals)
        if np.sum(np.einsum("ij,ij->i", Nn, P - P.mean(0))) < 0:
            pcd.normals = o3d.utility.Vector3dVector(-Nn)
    else:
        pcd.normals = o3d.utility.Vector3dVector(N)
    with o3d.utility.VerbosityContextManager(o3d.utility.VerbosityLevel.Error):
        if method == "poisson":
            mesh, dens = o3d.geometry.TriangleMesh.create_from_point_cloud_poisson(pcd, depth=depth)
            if trim > 0:
                dens = np.asarray(dens)
                mesh.remove_vertices_by_mask(dens < np.quantile(dens, trim))
        else:
            spacing = float(np.mean(pcd.compute_nearest_neighbor_distance()))
            radii = o3d.utility.DoubleVector([1.5 * spacing, 3 * spacing, 6 * spacing])
            mesh = o3d.geometry.TriangleMesh.create_from_point_cloud_ball_pivoting(pcd, radii)
    mesh.remove_unreferenced_vertices()
    if len(mesh.triangles) == 0:
        raise MeshError(f"the {method} reconstruction produced no triangles")
    # reconstructions often have non-manifold edges or vertices: split them, so that topology
    # (critical points, persistence) works on the surface (o3dheat.repair)
    return as_arrays(repair(mesh).mesh)
