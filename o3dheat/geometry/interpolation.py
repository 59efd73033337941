"""Functions moved between samplings of a surface: :func:`transfer` (the PL function of one
sampling at the vertices of another, barycentric at the closest surface point), its geometry alone
as a :class:`TransferMap` (:func:`transfer_map`: made once, applied to many fields) and
:func:`nearest` (the value of the nearest sample)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from scipy.spatial import cKDTree

from o3dheat import checks
from o3dheat.errors import MeshError

from .mesh import as_arrays
from .sampling import Resampled

if TYPE_CHECKING:  # o3dheat.typing imports Open3D (1.5 s), which arrays never need: for annotations only
    from numpy.typing import ArrayLike

    from o3dheat.typing import MeshLike

__all__ = ["transfer", "transfer_map", "TransferMap", "nearest"]


def _surface_of(source):
    if isinstance(source, Resampled):
        return source.V, source.F
    return as_arrays(source)


@dataclass(frozen=True, eq=False)
class TransferMap:
    """Where each target point lies on the source surface: a triangle's three vertices and the
    barycentric weights of the closest point in it. Calling it moves a field (:func:`transfer_map`).

    Attributes
    ----------
    corners : (p, 3) int64 ndarray
        The source vertices of the triangle closest to each target point.
    weights : (p, 3) float64 ndarray
        Their barycentric weights (>= 0, summing to 1) at the closest point.
    sources : int
        The number of source vertices (the rows a field must have).

    Examples
    --------
    See :func:`transfer_map`.
    """

    corners: np.ndarray
    weights: np.ndarray
    sources: int

    def __call__(self, values: ArrayLike) -> np.ndarray:
        """The PL function of ``values`` (one row per source vertex) at the target points:
        (p,) for (r,) values, (p, c) for (r, c)."""
        return self._gather(checks.field(values, self.sources, "values (one row per source vertex)"))

    def _gather(self, vals):
        """The move of checked values (``checks.field``)."""
        if vals.ndim == 1:
            return np.einsum("pk,pk->p", self.weights, vals[self.corners])
        return np.einsum("pk,pkc->pc", self.weights, vals[self.corners])


def transfer(values: ArrayLike, source: MeshLike, target: MeshLike | np.ndarray) -> np.ndarray:
    """Evaluate the PL function given at the vertices of ``source`` at the vertices of ``target``.

    Each target point is projected on the closest point of the source surface (Open3D's
    RaycastingScene) and gets the barycentric interpolation of that triangle's vertex values:
    exact for functions linear on the source triangles (coordinates, for example), and the
    identity when both samplings are the same mesh. Several fields between the same two samplings:
    :func:`transfer_map` once, then call it on each.

    Parameters
    ----------
    values : (r,) or (r, c) array_like
        One row per source vertex.
    source : Open3D mesh, (V, F) or Resampled
        The surface on whose vertices ``values`` are given.
    target : Open3D mesh, (V, F), Resampled, or (p, 3) array of points
        Where the function is evaluated: the vertices of a mesh, or points (projected on the closest
        point of the source).

    Returns
    -------
    (p,) or (p, c) float64 ndarray

    Examples
    --------
    >>> import numpy as np
    >>> from o3dheat.geometry.interpolation import transfer
    >>> V = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0.]]); F = np.array([[0, 1, 2]])
    >>> transfer(V[:, 0], (V, F), np.array([[0.25, 0.25, 1.0]])).round(6).tolist()
    [0.25]
    """
    V, F = _surface_of(source)
    vals = checks.field(values, len(V), "values (one row per source vertex)")  # before the geometry's work
    return transfer_map((V, F), target)._gather(vals)


def transfer_map(source: MeshLike, target: MeshLike | np.ndarray) -> TransferMap:
    """The geometry of :func:`transfer` alone: the closest source triangle of each target point and
    its barycentric weights, to move any number of fields afterwards (each a gather, no search).

    Parameters
    ----------
    source : Open3D mesh, (V, F) or Resampled
        The surface the fields are given on.
    target : Open3D mesh, (V, F), Resampled, or (p, 3) array of points
        Where they are evaluated.

    Returns
    -------
    TransferMap
        ``transfer_map(source, target)(values) == transfer(values, source, target)``.

    Raises
    ------
    MeshError
        NaN or infinite target points.

    Examples
    --------
    >>> import numpy as np
    >>> from o3dheat.geometry.interpolation import transfer_map
    >>> V = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0.]]); F = np.array([[0, 1, 2]])
    >>> move = transfer_map((V, F), np.array([[0.25, 0.25, 1.0], [0.5, 0.0, 0.0]]))
    >>> move(V[:, 0]).round(6).tolist(), move(V[:, :2]).round(6).tolist()
    ([0.25, 0.5], [[0.25, 0.25], [0.5, 0.0]])
    """
    import open3d as o3d

    V, F = _surface_of(source)
    if isinstance(target, np.ndarray) and target.ndim == 2 and target.shape[1] == 3:
        pts = np.asarray(target, dtype=np.float64)
        bad = ~np.isfinite(pts).all(axis=1)
        if bad.any():
            raise MeshError(f"target points: {int(bad.sum())} are NaN or infinite (first: point "
                            f"{int(np.flatnonzero(bad)[0])}); there is no closest point to them")
    else:
        pts = _surface_of(target)[0]
    # Open3D's closest-point scene is float32: centre and scale both point sets on the source's
    # bounding box first (georeferenced scans sit 1e6 units from the origin, where float32 steps
    # are 0.5 units); the barycentric coordinates are then computed in float64
    centre = (V.min(axis=0) + V.max(axis=0)) / 2
    size = float(np.max(np.ptp(V, axis=0))) or 1.0
    V, pts = (V - centre) / size, (np.asarray(pts, dtype=np.float64) - centre) / size
    scene = o3d.t.geometry.RaycastingScene()
    tm = o3d.t.geometry.TriangleMesh()
    tm.vertex.positions = o3d.core.Tensor(V.astype(np.float32))
    tm.triangle.indices = o3d.core.Tensor(np.asarray(F, dtype=np.uint32))
    scene.add_triangles(tm)
    ans = scene.compute_closest_points(o3d.core.Tensor(pts.astype(np.float32)))
    tri = ans["primitive_ids"].numpy().astype(np.int64)
    # barycentric coordinates in float64 at the float32 closest point, for exactness
    corner = np.asarray(F, dtype=np.int64)[tri]
    w = _barycentric(pts, V[corner[:, 0]], V[corner[:, 1]], V[corner[:, 2]])
    return TransferMap(corner, w, len(V))


def _barycentric(p, a, b, c):
    """Barycentric coordinates of the closest point of triangle abc to p (clamped to the triangle)."""
    ab, ac = b - a, c - a
    n = np.cross(ab, ac)
    nn = np.einsum("ij,ij->i", n, n)
    q = p - (np.einsum("ij,ij->i", p - a, n) / np.where(nn > 0, nn, 1.0))[:, None] * n  # onto the plane
    aq = q - a
    d00, d01, d11 = np.einsum("ij,ij->i", ab, ab), np.einsum("ij,ij->i", ab, ac), np.einsum("ij,ij->i", ac, ac)
    d20, d21 = np.einsum("ij,ij->i", aq, ab), np.einsum("ij,ij->i", aq, ac)
    den = d00 * d11 - d01 * d01
    den = np.where(den > 0, den, 1.0)
    v = (d11 * d20 - d01 * d21) / den
    w = (d00 * d21 - d01 * d20) / den
    u = 1.0 - v - w
    W = np.clip(np.stack([u, v, w], 1), 0.0, None)
    return W / W.sum(axis=1, keepdims=True)


def nearest(values: ArrayLike, source: ArrayLike, points: ArrayLike) -> np.ndarray:
    """Values at the nearest of the ``source`` positions (a k-d tree), for each of ``points``.

    Examples
    --------
    >>> from o3dheat.geometry.interpolation import nearest
    >>> nearest([1.0, 2.0], [[0, 0, 0], [1, 0, 0]], [[0.9, 0, 0]]).tolist()
    [2.0]
    """
    vals = np.asarray(checks.values(values))
    try:
        src = np.asarray(source, dtype=np.float64).reshape(-1, 3)
        pts = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    except (TypeError, ValueError):
        raise MeshError("source and points must be (n, 3) arrays of coordinates") from None
    if len(src) == 0 or len(vals) != len(src):
        raise MeshError(f"nearest needs one value per source position and at least one: {len(vals)} values, "
                        f"{len(src)} positions")
    if not (np.isfinite(src).all() and np.isfinite(pts).all()):
        raise MeshError("source positions and points must be finite (NaN or infinite coordinates given)")
    _, idx = cKDTree(src).query(pts)
    return vals[idx]
