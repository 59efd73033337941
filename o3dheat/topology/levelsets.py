"""Level sets of a PL field as line segments (marching triangles), for figures: :func:`level_sets`."""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np

from o3dheat import checks
from o3dheat.errors import MeshError
from o3dheat.typing import FieldLike, MeshLike

from .surface import Surface

if TYPE_CHECKING:  # annotations only: Open3D is imported where it is used (it takes seconds)
    import open3d as o3d

__all__ = ["level_sets"]


def level_sets(mesh: MeshLike | Surface, f: FieldLike, values: Sequence[float] | None = None, count: int | None = None,
               color: Sequence[float] = (0.0, 0.0, 0.0)) -> o3d.geometry.LineSet:
    """Level sets of a PL field as line segments (marching triangles), for figures.

    Parameters
    ----------
    mesh : o3d.t.geometry.TriangleMesh, o3d.geometry.TriangleMesh or (V, F) tuple
        The surface.
    f : (n,) array_like
        The field, one value per vertex.
    values : sequence of float, optional
        The iso-values.
    count : int, optional
        Instead of values: ``count`` values evenly spaced strictly inside ``[min f, max f]``.
        Default 10 when neither is given.
    color : 3 floats in [0, 1]
        Colour of every line.

    Returns
    -------
    o3d.geometry.LineSet
        One segment per triangle crossed by each value; points are shared between adjacent
        triangles. A vertex exactly at a value counts as above it, so a level set never
        doubles back along an edge.

    Examples
    --------
    >>> import open3d as o3d, o3dheat
    >>> mesh = o3d.t.geometry.TriangleMesh.create_sphere(1.0, 20)
    >>> ls = o3dheat.level_sets(mesh, mesh.vertex.positions.numpy()[:, 2], values=[0.0])
    >>> len(ls.lines) > 0
    True
    """
    import open3d as o3d

    S = Surface.of(mesh)
    if S.V is None:
        raise MeshError("level_sets needs vertex coordinates: pass a mesh or (V, F)")
    f = S.field(f)
    vals = f[S.used]
    if values is None:
        count = checks.count(10 if count is None else count, "count", maximum=10_000)
        values = np.linspace(vals.min(), vals.max(), count + 2)[1:-1]
    elif count is not None:
        raise MeshError("give values or count, not both")
    values = np.atleast_1d(np.asarray(values, dtype=np.float64))
    if values.ndim != 1 or not np.all(np.isfinite(values)):
        raise MeshError("values must be a 1-D sequence of finite numbers")
    V, E, FE = S.V, S.E, S.face_edges
    pts, lines, npts = [], [], 0
    for c in values:
        above = f >= c
        cross = above[E[:, 0]] != above[E[:, 1]]
        ce = np.flatnonzero(cross)
        i, j = E[ce, 0], E[ce, 1]
        w = (c - f[i]) / (f[j] - f[i])
        pts.append(V[i] + w[:, None] * (V[j] - V[i]))
        pid = np.full(len(E), -1, np.int64)
        pid[ce] = npts + np.arange(len(ce))
        npts += len(ce)
        cf = cross[FE]
        tri = np.flatnonzero(cf.sum(axis=1) == 2)
        first = np.argmax(cf[tri], axis=1)
        last = 2 - np.argmax(cf[tri][:, ::-1], axis=1)
        lines.append(np.stack([pid[FE[tri, first]], pid[FE[tri, last]]], axis=1))
    P = np.concatenate(pts) if pts else np.zeros((0, 3))
    Lz = np.concatenate(lines) if lines else np.zeros((0, 2), np.int64)
    ls = o3d.geometry.LineSet(o3d.utility.Vector3dVector(P), o3d.utility.Vector2iVector(Lz.astype(np.int32)))
    if len(Lz):
        ls.colors = o3d.utility.Vector3dVector(np.tile(np.asarray(color, dtype=np.float64), (len(Lz), 1)))
    return ls
