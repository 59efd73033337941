"""Samplings of a surface and the transfer of functions between them.

* :func:`decimate`: an irregular, curvature-adaptive sampling of a mesh (fast-simplification's
  quadric decimation keeps detail where the surface bends).
* :func:`reconstruct`: a triangle mesh from a point cloud (Open3D's Poisson or ball-pivoting
  reconstruction), so that the FEM operators can be built for points.
* :func:`transfer`: per-vertex values of a mesh evaluated at other points, by linear
  (barycentric) interpolation at the closest point of the surface — the PL function itself.
* :func:`nearest`: values at the nearest sample (for points to mesh vertices).
"""

from __future__ import annotations

import numpy as np

from .errors import MeshError
from .mesh import as_arrays

__all__ = ["decimate", "reconstruct", "transfer", "nearest", "point_arrays"]


def point_arrays(cloud):
    """Positions (n, 3) float64 and normals (n, 3) or None of an Open3D point cloud (tensor or legacy)."""
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


def decimate(mesh, reduction=0.7, target_faces=None):
    """Quadric decimation (fast-simplification): fewer vertices where the surface is flat.

    Parameters
    ----------
    mesh : Open3D mesh or (V, F)
    reduction : float in [0, 1)
        Fraction of the faces to remove.
    target_faces : int, optional
        Instead of ``reduction``: the number of faces to keep (no-op when the mesh has fewer).

    Returns
    -------
    V : (r, 3) float64 ndarray
    F : (m, 3) int64 ndarray

    Examples
    --------
    >>> import open3d as o3d
    >>> from o3dheat.sampling import decimate
    >>> V, F = decimate(o3d.t.geometry.TriangleMesh.create_sphere(1.0, 40), reduction=0.5)
    >>> len(F)                # half of the 6240 faces
    3120
    """
    import fast_simplification

    V, F = as_arrays(mesh)
    if target_faces is not None:
        if target_faces >= len(F):
            return V, F
        reduction = 1.0 - target_faces / len(F)
    if not 0.0 <= reduction < 1.0:
        raise MeshError(f"reduction must lie in [0, 1), got {reduction}")
    if reduction == 0:
        return V, F
    V2, F2 = fast_simplification.simplify(V, F.astype(np.int32), target_reduction=float(reduction))
    return _manifold(np.asarray(V2, np.float64), np.asarray(F2, np.int64))


def _manifold(V, F):
    """Degenerate and duplicate faces removed, and the faces at non-manifold edges and vertices
    (rare after a decimation, fatal to the topology): a 2-manifold, logged when changed."""
    import logging

    import open3d as o3d

    m = o3d.geometry.TriangleMesh(o3d.utility.Vector3dVector(V), o3d.utility.Vector3iVector(F.astype(np.int32)))
    m.remove_degenerate_triangles()
    m.remove_duplicated_triangles()
    for _ in range(5):
        bad_v = np.asarray(m.get_non_manifold_vertices())
        before = len(m.triangles)
        m.remove_non_manifold_edges()
        if len(bad_v):
            T = np.asarray(m.triangles)
            m.remove_triangles_by_mask(np.isin(T, bad_v).any(axis=1))
        if len(m.triangles) == before and not len(bad_v):
            break
    m.remove_unreferenced_vertices()
    if len(m.triangles) < len(F):
        logging.getLogger("o3dheat").info("decimate: %d faces removed to keep a 2-manifold",
                                          len(F) - len(m.triangles))
    return np.asarray(m.vertices, np.float64), np.asarray(m.triangles, np.int64)


def reconstruct(cloud, method="poisson", depth=8, neighbours=30, trim=0.0):
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
    >>> from o3dheat.sampling import reconstruct
    >>> P = np.random.default_rng(0).standard_normal((3000, 3)); P /= np.linalg.norm(P, axis=1)[:, None]
    >>> V, F = reconstruct(o3d.t.geometry.PointCloud(o3d.core.Tensor(P)))
    >>> bool(abs(np.linalg.norm(V, axis=1).mean() - 1) < 0.02)
    True
    """
    import open3d as o3d

    if method not in ("poisson", "ball_pivoting"):
        raise MeshError(f"unknown reconstruction {method!r}: use 'poisson' or 'ball_pivoting'")
    P, N = point_arrays(cloud)
    if len(P) < 10:
        raise MeshError(f"{len(P)} points are too few to reconstruct a surface")
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
    return as_arrays(mesh)


def transfer(values, V, F, points):
    """Evaluate a PL function given at the vertices of ``(V, F)`` at other points.

    Each point is projected on the closest point of the surface and the value there is the
    barycentric interpolation of the triangle's vertex values.

    Parameters
    ----------
    values : (r,) or (r, c) array_like
    V : (r, 3) float64 ndarray
    F : (m, 3) int ndarray
    points : (p, 3) array_like

    Returns
    -------
    (p,) or (p, c) float64 ndarray

    Examples
    --------
    >>> import numpy as np
    >>> from o3dheat.sampling import transfer
    >>> V = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0.]]); F = np.array([[0, 1, 2]])
    >>> transfer(V[:, 0], V, F, [[0.25, 0.25, 1.0]]).round(6).tolist()
    [0.25]
    """
    import open3d as o3d

    vals = np.asarray(values, dtype=np.float64)
    if vals.shape[0] != len(V):
        raise MeshError(f"values have {vals.shape[0]} rows for {len(V)} vertices")
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    scene = o3d.t.geometry.RaycastingScene()
    tm = o3d.t.geometry.TriangleMesh()
    tm.vertex.positions = o3d.core.Tensor(V.astype(np.float32))
    tm.triangle.indices = o3d.core.Tensor(np.asarray(F, dtype=np.uint32))
    scene.add_triangles(tm)
    ans = scene.compute_closest_points(o3d.core.Tensor(pts.astype(np.float32)))
    tri = ans["primitive_ids"].numpy().astype(np.int64)
    uv = ans["primitive_uvs"].numpy().astype(np.float64)
    w = np.stack([1 - uv[:, 0] - uv[:, 1], uv[:, 0], uv[:, 1]], 1)
    corner = np.asarray(F, dtype=np.int64)[tri]
    if vals.ndim == 1:
        return np.einsum("pk,pk->p", w, vals[corner])
    return np.einsum("pk,pkc->pc", w, vals[corner])


def nearest(values, source, points):
    """Values at the nearest of the ``source`` positions (a k-d tree), for each of ``points``.

    Examples
    --------
    >>> from o3dheat.sampling import nearest
    >>> nearest([1.0, 2.0], [[0, 0, 0], [1, 0, 0]], [[0.9, 0, 0]]).tolist()
    [2.0]
    """
    from scipy.spatial import cKDTree

    vals = np.asarray(values)
    _, idx = cKDTree(np.asarray(source, dtype=np.float64)).query(np.asarray(points, dtype=np.float64))
    return vals[idx]
