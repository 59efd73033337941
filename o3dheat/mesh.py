"""Open3D meshes (tensor and legacy) and ``(V, F)`` arrays: conversion, validation and repair.

This module is the only one that knows about Open3D mesh types. Everything downstream works on
plain arrays: vertices ``V`` as ``(n, 3) float64`` and faces ``F`` as ``(m, 3) int64``.

Repairs applied before any FEM computation (see :func:`prepare`), each logged as a warning:

* faces that repeat a vertex index (``[i, i, j]``) and exact duplicate faces are dropped;
* faces of zero area (collinear or coincident corners) are dropped: they carry no surface, so
  they contribute nothing to the FEM integrals, and their cotangent weights are undefined;
* vertices referenced by no remaining face are set aside: the computation runs on the referenced
  vertices and results are mapped back, with the value 0 at the unreferenced ones (an isolated
  point carries no area, so no FEM function "sees" it).

Duplicate vertices (equal coordinates, different indices) and non-manifold edges or vertices are
reported by :func:`check_mesh` but are valid input: the linear FEM sums over every triangle at an
edge, and duplicate vertices simply form a seam (two boundary curves).
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

from .errors import MeshError

__all__ = ["as_arrays", "check_mesh", "MeshReport", "prepare", "Prepared", "face_areas"]

log = logging.getLogger("o3dheat")


def _from_open3d(mesh):
    if not type(mesh).__module__.startswith("open3d"):
        return None  # arrays: no need to import Open3D (1.5 s and 200 MB the first time)
    try:
        import open3d as o3d
    except ImportError:  # pragma: no cover - open3d is a required dependency
        return None
    if isinstance(mesh, o3d.t.geometry.TriangleMesh):
        if "positions" not in mesh.vertex:
            raise MeshError("the tensor mesh has no vertex positions: it is empty")
        V = mesh.vertex.positions.numpy()
        F = mesh.triangle.indices.numpy() if "indices" in mesh.triangle else np.zeros((0, 3), int)
        return V, F
    if isinstance(mesh, o3d.geometry.TriangleMesh):
        return np.asarray(mesh.vertices), np.asarray(mesh.triangles)
    if isinstance(mesh, (o3d.t.geometry.PointCloud, o3d.geometry.PointCloud)):
        raise MeshError("got a point cloud, expected a triangle mesh: reconstruct a surface first "
                        "(for example o3d.geometry.TriangleMesh.create_from_point_cloud_poisson)")
    return None


def _pair(mesh):
    """(V, F) as given: from an Open3D mesh or a 2-sequence, not yet checked."""
    pair = _from_open3d(mesh)
    if pair is None:
        if not isinstance(mesh, (tuple, list)) or len(mesh) != 2:
            raise MeshError(f"expected an Open3D TriangleMesh or a (V, F) tuple, got {type(mesh).__name__}")
        pair = mesh
    return pair


def _degenerate(F):
    """Faces that repeat a vertex index."""
    return (F[:, 0] == F[:, 1]) | (F[:, 1] == F[:, 2]) | (F[:, 0] == F[:, 2])


def as_arrays(mesh):
    """Return the vertices and faces of a mesh as checked numpy arrays.

    Parameters
    ----------
    mesh : o3d.t.geometry.TriangleMesh, o3d.geometry.TriangleMesh or (V, F) tuple
        The surface. ``V`` is ``(n, 3)`` real, ``F`` is ``(m, 3)`` integer (0-based).

    Returns
    -------
    V : (n, 3) float64 ndarray
        Vertex coordinates (a new array; the input is never modified).
    F : (m, 3) int64 ndarray
        Triangle vertex indices.

    Raises
    ------
    MeshError
        Empty mesh, no faces, wrong shapes, non-finite coordinates, or face indices out of range.

    Examples
    --------
    >>> import open3d as o3d, o3dheat
    >>> V, F = o3dheat.as_arrays(o3d.t.geometry.TriangleMesh.create_sphere(1.0, 8))
    >>> V.shape[1], F.shape[1], V.dtype.name, F.dtype.name
    (3, 3, 'float64', 'int64')
    """
    pair = _pair(mesh)
    V = np.array(pair[0], dtype=np.float64, copy=True)
    F_in = np.asarray(pair[1])
    if V.size == 0:
        raise MeshError("the mesh is empty (no vertices)")
    if V.ndim != 2 or V.shape[1] != 3:
        raise MeshError(f"vertices must have shape (n, 3), got {V.shape}")
    if F_in.size == 0:
        raise MeshError("the mesh has no faces: o3dheat needs a triangle mesh, not a point set")
    if F_in.ndim != 2 or F_in.shape[1] != 3:
        raise MeshError(f"faces must have shape (m, 3) (triangles), got {F_in.shape}")
    if not np.issubdtype(F_in.dtype, np.integer):
        if not np.all(np.isfinite(F_in)) or np.any(F_in != np.round(F_in)):
            raise MeshError("face indices must be integers")
    F = F_in.astype(np.int64, copy=True)
    bad = ~np.all(np.isfinite(V), axis=1)
    if bad.any():
        raise MeshError(f"{int(bad.sum())} vertices have NaN or infinite coordinates "
                        f"(first: {int(np.flatnonzero(bad)[0])}); remove or fix them first")
    if F.min() < 0 or F.max() >= len(V):
        raise MeshError(f"face indices out of range: they must lie in [0, {len(V) - 1}], "
                        f"found [{int(F.min())}, {int(F.max())}]")
    return V, F


def face_areas(V, F):
    """Areas of the triangles.

    Parameters
    ----------
    V : (n, 3) float64 ndarray
    F : (m, 3) int ndarray

    Returns
    -------
    (m,) float64 ndarray
        ``|t| = ||(v1 - v0) x (v2 - v0)|| / 2``, in squared units of ``V``.

    Examples
    --------
    >>> import numpy as np, o3dheat.mesh as m
    >>> m.face_areas(np.eye(3), np.array([[0, 1, 2]])).round(4)
    array([0.866])
    """
    v0, v1, v2 = V[F[:, 0]], V[F[:, 1]], V[F[:, 2]]
    return 0.5 * np.linalg.norm(np.cross(v1 - v0, v2 - v0), axis=1)


def _unique_rows(A, return_index=False, return_counts=False):
    """``np.unique(A, axis=0, ...)`` for rows of non-negative integers, 5-10x faster: each row is
    packed into one int64 key when that fits (the general path otherwise)."""
    A = np.asarray(A, dtype=np.int64)
    base = int(A.max()) + 1 if A.size else 1
    c = A.shape[1] if A.ndim == 2 else 1
    if A.ndim != 2 or A.min(initial=0) < 0 or c * np.log2(max(base, 2)) >= 62:
        return np.unique(A, axis=0, return_index=return_index, return_counts=return_counts)
    key = np.zeros(len(A), np.int64)
    for j in range(c):
        key = key * base + A[:, j]
    out = np.unique(key, return_index=True, return_counts=return_counts)
    rows = A[out[1]]
    res = (rows,) + ((out[1],) if return_index else ()) + ((out[2],) if return_counts else ())
    return res if len(res) > 1 else rows


def _edges(F):
    """Unique undirected edges (e, 2) and, for each, the number of incident faces."""
    E = np.sort(np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]]), axis=1)
    E, counts = _unique_rows(E, return_counts=True)
    return E, counts


def _zero_area(V, F):
    area = face_areas(V, F)
    scale = np.max(np.ptp(V, axis=0)) if len(V) else 1.0
    return area <= 1e-14 * max(scale, np.finfo(float).tiny) ** 2


@dataclass
class MeshReport:
    """What :func:`check_mesh` found. ``str(report)`` gives a readable summary.

    Attributes are counts (int) unless said otherwise; ``ok`` is True when o3dheat will use the
    mesh as it is, without any repair.
    """

    n_vertices: int
    n_faces: int
    degenerate_faces: int  # faces that repeat a vertex index
    zero_area_faces: int  # distinct corners but no area
    duplicate_faces: int
    unreferenced_vertices: int
    duplicate_vertices: int  # vertices sharing coordinates with an earlier one
    non_manifold_edges: int  # edges with more than two faces
    non_manifold_vertices: int  # vertices whose faces form more than one fan
    boundary_edges: int
    boundary_loops: int
    components: int
    non_finite_vertices: int
    euler_characteristic: int
    genus: float | None  # None when not defined (non-manifold)
    area: float
    problems: list = field(default_factory=list)

    @property
    def ok(self):
        return not self.problems

    def __str__(self):
        g = "n/a" if self.genus is None else (f"{self.genus:g}")
        lines = [
            f"vertices: {self.n_vertices}   faces: {self.n_faces}   area: {self.area:.6g}",
            f"components: {self.components}   boundary loops: {self.boundary_loops}   "
            f"Euler characteristic: {self.euler_characteristic}   genus: {g}",
            f"degenerate faces: {self.degenerate_faces}   zero-area faces: {self.zero_area_faces}   "
            f"duplicate faces: {self.duplicate_faces}",
            f"unreferenced vertices: {self.unreferenced_vertices}   duplicate vertices: "
            f"{self.duplicate_vertices}   non-finite vertices: {self.non_finite_vertices}",
            f"non-manifold edges: {self.non_manifold_edges}   non-manifold vertices: "
            f"{self.non_manifold_vertices}",
        ]
        lines.append("status: ok" if self.ok else "status: " + "; ".join(self.problems))
        return "\n".join(lines)


def _boundary_loops(bE):
    """Number of closed boundary curves (cycles of the boundary-edge graph)."""
    if len(bE) == 0:
        return 0
    nodes, inv = np.unique(bE, return_inverse=True)
    inv = inv.reshape(-1, 2)
    g = sp.coo_matrix((np.ones(len(inv)), (inv[:, 0], inv[:, 1])), shape=(len(nodes),) * 2)
    return int(connected_components(g, directed=False)[0])


def _non_manifold_vertices(F, n):
    """Vertices whose incident faces form more than one edge-connected fan."""
    m = len(F)
    if m == 0:
        return 0
    # corner c = (face, slot); two corners at the same vertex are adjacent when their faces share
    # the edge (vertex, other) -- join corners through the "half-edge key" (vertex, other vertex).
    vert = F.reshape(-1)
    nxt = F[:, [1, 2, 0]].reshape(-1)
    prv = F[:, [2, 0, 1]].reshape(-1)
    keys = np.concatenate([vert * n + nxt, vert * n + prv])
    corner = np.concatenate([np.arange(3 * m), np.arange(3 * m)])
    order = np.argsort(keys, kind="stable")
    ks, cs = keys[order], corner[order]
    same = ks[1:] == ks[:-1]
    a, b = cs[:-1][same], cs[1:][same]
    g = sp.coo_matrix((np.ones(len(a)), (a, b)), shape=(3 * m, 3 * m))
    _, lab = connected_components(g, directed=False)
    fans = np.unique(np.stack([vert, lab], axis=1), axis=0)
    per_vertex = np.bincount(fans[:, 0], minlength=n)
    return int(np.sum(per_vertex > 1))


def check_mesh(mesh):
    """Inspect a mesh and report everything that matters to the FEM operators.

    Unlike :func:`as_arrays` it never raises on a bad mesh (except when it cannot read one at
    all); it counts the problems instead.

    Parameters
    ----------
    mesh : o3d.t.geometry.TriangleMesh, o3d.geometry.TriangleMesh or (V, F) tuple

    Returns
    -------
    MeshReport
        Counts of degenerate, zero-area and duplicate faces, unreferenced and duplicate vertices,
        non-manifold edges and vertices, boundary loops, connected components, non-finite
        coordinates; the Euler characteristic ``V - E + F`` (of the referenced part) and the
        genus ``(2 c - chi - b) / 2`` (for a manifold mesh, with ``c`` components and ``b``
        boundary loops).

    Examples
    --------
    >>> import open3d as o3d, o3dheat
    >>> r = o3dheat.check_mesh(o3d.t.geometry.TriangleMesh.create_torus())
    >>> r.euler_characteristic, r.genus, r.ok
    (0, 1.0, True)
    """
    pair = _pair(mesh)
    V = np.asarray(pair[0], dtype=np.float64).reshape(-1, 3)
    F = np.asarray(pair[1]).reshape(-1, 3).astype(np.int64)
    n, m = len(V), len(F)
    problems = []
    nonfinite = int(np.sum(~np.all(np.isfinite(V), axis=1)))
    if n == 0:
        problems.append("no vertices")
    if m == 0:
        problems.append("no faces")
    if m and (F.min() < 0 or F.max() >= n):
        problems.append("face indices out of range")
        F = F[np.all((F >= 0) & (F < n), axis=1)]
        m = len(F)
    if nonfinite:
        problems.append(f"{nonfinite} non-finite vertices")
    degenerate = _degenerate(F)
    Fs = np.sort(F[~degenerate], axis=1)
    dup_faces = len(Fs) - len(_unique_rows(Fs)) if len(Fs) else 0
    finite = np.all(np.isfinite(V), axis=1)
    good = F[~degenerate]
    zero = int(np.sum(_zero_area(np.where(finite[:, None], V, 0.0), good))) if len(good) else 0
    used = np.zeros(n, bool)
    used[F.reshape(-1)] = True
    unref = int(n - used.sum())
    _, first = np.unique(V, axis=0, return_index=True) if n else (None, np.zeros(0))
    dup_verts = int(n - len(first))
    E, counts = _edges(good) if len(good) else (np.zeros((0, 2), int), np.zeros(0, int))
    nm_edges = int(np.sum(counts > 2))
    bE = E[counts == 1]
    loops = _boundary_loops(bE)
    nm_verts = _non_manifold_vertices(good, n) if len(good) else 0
    if len(good):
        g = sp.coo_matrix((np.ones(len(E)), (E[:, 0], E[:, 1])), shape=(n, n))
        ncomp_all, lab = connected_components(g, directed=False)
        components = len(np.unique(lab[np.unique(good)]))
    else:
        components = 0
    chi = int(used.sum() - len(E) + len(good)) if len(good) else 0
    genus = None
    if nm_edges == 0 and nm_verts == 0 and len(good):
        genus = (2 * components - chi - loops) / 2
    area = float(face_areas(np.where(finite[:, None], V, 0.0), good).sum()) if len(good) else 0.0
    if degenerate.any():
        problems.append(f"{int(degenerate.sum())} degenerate faces (dropped)")
    if zero:
        problems.append(f"{zero} zero-area faces (dropped)")
    if dup_faces:
        problems.append(f"{dup_faces} duplicate faces (dropped)")
    if unref:
        problems.append(f"{unref} unreferenced vertices (set aside, value 0 in results)")
    return MeshReport(n, int(len(F)), int(degenerate.sum()), zero, int(dup_faces), unref, dup_verts,
                      nm_edges, nm_verts, int(len(bE)), loops, int(components), nonfinite, chi,
                      genus, area, problems)


@dataclass(frozen=True)
class Prepared:
    """A mesh ready for the FEM operators, and the way back to the caller's vertex numbering.

    Attributes
    ----------
    V : (r, 3) float64 ndarray
        The referenced vertices.
    F : (m, 3) int64 ndarray
        Faces re-indexed into ``V``.
    keep : (r,) int64 ndarray
        ``keep[j]`` is the caller's index of vertex ``j``.
    n_input : int
        Number of vertices of the caller's mesh.
    """

    V: np.ndarray
    F: np.ndarray
    keep: np.ndarray
    n_input: int

    def expand(self, X):
        """Map per-vertex values (r, ...) back to the caller's n_input vertices (0 elsewhere)."""
        X = np.asarray(X)
        if len(self.keep) == self.n_input:
            return X
        out = np.zeros((self.n_input,) + X.shape[1:], dtype=X.dtype)
        out[self.keep] = X
        return out

    def restrict(self, f):
        """Per-vertex values of the caller's mesh (n_input, ...) restricted to the kept vertices."""
        f = np.asarray(f)
        return f if len(self.keep) == self.n_input else f[self.keep]


def prepare(mesh):
    """Convert and repair a mesh for the FEM operators (see the module docstring for the rules).

    Parameters
    ----------
    mesh : o3d.t.geometry.TriangleMesh, o3d.geometry.TriangleMesh or (V, F) tuple

    Returns
    -------
    Prepared

    Raises
    ------
    MeshError
        When :func:`as_arrays` does, or when no face with positive area is left.

    Examples
    --------
    >>> import numpy as np, o3dheat.mesh as m
    >>> V = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [5, 5, 5.]])
    >>> p = m.prepare((V, np.array([[0, 1, 2]])))
    >>> p.keep.tolist(), p.n_input
    ([0, 1, 2], 4)
    """
    V, F = as_arrays(mesh)
    n = len(V)
    degenerate = _degenerate(F)
    if degenerate.any():
        log.warning("dropping %d degenerate faces (a vertex index repeated)", int(degenerate.sum()))
        F = F[~degenerate]
    if len(F):
        _, first = _unique_rows(np.sort(F, axis=1), return_index=True)
        if len(first) < len(F):
            log.warning("dropping %d duplicate faces", len(F) - len(first))
            F = F[np.sort(first)]
    if len(F):
        zero = _zero_area(V, F)
        if zero.any():
            log.warning("dropping %d zero-area faces", int(zero.sum()))
            F = F[~zero]
    if len(F) == 0:
        raise MeshError("no face with a positive area is left: the mesh is degenerate")
    used = np.zeros(n, bool)
    used[F.reshape(-1)] = True
    if used.all():
        return Prepared(V, F, np.arange(n), n)
    keep = np.flatnonzero(used)
    log.warning("%d unreferenced vertices set aside; they get the value 0 in every result", n - len(keep))
    remap = np.full(n, -1, dtype=np.int64)
    remap[keep] = np.arange(len(keep))
    return Prepared(V[keep], remap[F], keep, n)
