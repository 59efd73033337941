"""Open3D meshes (tensor and legacy) and ``(V, F)`` arrays: conversion, validation and repair.

This module is the only one that knows about Open3D mesh types. Everything downstream works on
plain arrays: vertices ``V`` as ``(n, 3) float64`` and faces ``F`` as ``(m, 3) int64``.

Repairs applied before any FEM computation (see :func:`prepare`), each logged as a warning:

* duplicate vertices -- referenced vertices with exactly equal ``float64`` coordinates, as in STL
  files and other "triangle soups" where every face has its own three vertex copies -- are
  **welded** into one vertex (the copy with the smallest index), first, so that the faces around
  them share it. Without this, such a file is thousands of one-triangle components and every
  result is garbage. Results still come back per input vertex: each copy gets the value of its
  welded vertex. A per-vertex field given by the caller is averaged over the copies of each
  vertex (``restrict``), so ``K_t`` keeps constants and a field equal on the copies is used as
  is. ``prepare(mesh, weld=False)`` keeps the copies apart (each then lies on a seam, a
  boundary curve);
* faces that repeat a vertex index (``[i, i, j]``) and exact duplicate faces are dropped (after
  welding: a face with two coincident corners, or two copies of one face, is one of them);
* faces of zero area (collinear or coincident corners) are dropped: they carry no surface, so
  they contribute nothing to the FEM integrals, and their cotangent weights are undefined;
* vertices referenced by no remaining face are set aside: the computation runs on the referenced
  vertices and results are mapped back, with the value 0 at the unreferenced ones (an isolated
  point carries no area, so no FEM function "sees" it). An unreferenced vertex is never welded,
  even when it lies exactly on a referenced one.

The operators on the caller's vertices are built from those of the welded mesh (``L``, ``B``;
``r`` welded vertices): with ``P`` the ``n x r`` 0/1 matrix of the weld map (``P[i, w[i]] = 1``)
and ``D = diag(Pᵀ 1)`` the multiplicities, ``L_in = P D⁻¹ L D⁻¹ Pᵀ`` and
``B_in = P D⁻¹ B D⁻¹ Pᵀ``. The expanded eigenvectors ``X_in = P X`` then satisfy
``L_in X_in = B_in X_in Λ`` and ``X_inᵀ B_in X_in = I``, ``1ᵀ B_in 1`` is the area and the heat
kernel ``X_in D_t X_inᵀ B_in = P X D_t Xᵀ B D⁻¹ Pᵀ`` averages the copies and keeps constants.

Welding joins copies only across edges with exactly two faces: coincident vertices with a fan
of faces each (a pinched vertex of a triangle soup, the copies :func:`repair` makes) stay apart,
and the weld's warning and :func:`check_mesh` (``split_vertices``) say how many. A soup cannot
tell one vertex with two fans from two coincident vertices with a fan each; an indexed file
(OBJ, PLY) can, and is taken as it is.

Non-manifold edges or vertices are reported by :func:`check_mesh` (its status is then not ok)
but are valid input to the FEM: the linear FEM sums over every triangle at an edge. Topology
(:mod:`o3dheat.topology`) needs a 2-manifold and refuses them; it welds duplicate vertices the
same way.

Every function taking a mesh takes a mesh-like too: an object with a ``mesh`` attribute holding
an Open3D mesh or ``(V, F)`` (:func:`mesh_of`; :class:`Repaired`, ``sampling.Resampled``).
"""

from __future__ import annotations

import hashlib
import logging
import threading
from collections import OrderedDict
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

from o3dheat import checks
from o3dheat.errors import MeshError

from ._tables import (
    corner_components,
    corner_pairs,
    degenerate,
    edges,
    first_copies,
    first_faces,
    non_manifold_vertices,
    unit_scale,
    weld_copies,
    zero_area,
)

__all__ = ["as_arrays", "mesh_of", "check_points", "check_mesh", "MeshReport", "prepare", "Prepared", "face_areas", "repair", "Repaired"]

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


def mesh_of(mesh):
    """The mesh an object stands for: the object itself when it is an Open3D mesh or a ``(V, F)``
    pair, else its ``mesh`` attribute (followed while it is another such object).

    This is the one mesh-like protocol of o3dheat: every function that takes a mesh (filters,
    :func:`o3dheat.eigensolve`, :func:`o3dheat.critical_points`, ...) takes any object with a
    ``mesh`` attribute holding an Open3D triangle mesh or a ``(V, F)`` pair -- a
    :class:`Repaired` (:func:`repair`), a :class:`o3dheat.geometry.sampling.Resampled`, or one of yours.
    Other objects are returned as they are (the caller refuses them).

    Examples
    --------
    >>> import numpy as np, o3dheat
    >>> V, F = np.eye(3), np.array([[0, 1, 2]])
    >>> r = o3dheat.repair((V, F))
    >>> type(o3dheat.geometry.mesh.mesh_of(r)).__name__, o3dheat.geometry.mesh.mesh_of((V, F))[1].tolist()
    ('TriangleMesh', [[0, 1, 2]])
    """
    for _ in range(8):  # a chain of wrappers, not a cycle
        if isinstance(mesh, (tuple, list)) or type(mesh).__module__.startswith("open3d"):
            return mesh
        inner = getattr(mesh, "mesh", None)
        if inner is None or inner is mesh:
            return mesh
        mesh = inner
    return mesh


def _pair(mesh):
    """(V, F) as given: from an Open3D mesh, a 2-sequence or a mesh-like (:func:`mesh_of`), not
    yet checked."""
    mesh = mesh_of(mesh)
    pair = _from_open3d(mesh)
    if pair is None:
        if not isinstance(mesh, (tuple, list)) or len(mesh) != 2:
            raise MeshError(f"expected an Open3D TriangleMesh, a (V, F) tuple or an object with a "
                            f"`mesh` attribute holding one (o3dheat.repair's, a resampling), "
                            f"got {type(mesh).__name__}")
        pair = (checks.values(mesh[0]), checks.values(mesh[1]))
    return pair


_NOTED_LOCK = threading.Lock()
_NOTED: OrderedDict = OrderedDict()  # (fingerprint of the arrays, topic) -> None, newest last


def note_repair(arrays, topic, message, *args):
    """Log a repair (a warning on the ``o3dheat`` logger: welded vertices, dropped faces...) once
    per geometry and ``topic`` ("weld", "degenerate", "duplicate", "zero-area", "unreferenced"):
    the same mesh goes through :func:`prepare` for its spectrum and through
    :class:`o3dheat.topology.Surface` for its critical points, and a chain of filters reads it at
    each step; the user hears of each repair once. ``arrays`` (the geometry the repair is about,
    as the caller was given them: ``(V, F)`` or ``(F,)``) are fingerprinted with BLAKE2b (about
    50 ms for a million vertices); the last 64 notes are remembered.

    Examples
    --------
    >>> import numpy as np, o3dheat.geometry.mesh as m
    >>> F = np.array([[0, 1, 2], [0, 1, 2]])
    >>> m.note_repair((F,), "duplicate", "dropping %d duplicate faces", 1)    # logged
    >>> m.note_repair((F,), "duplicate", "dropping %d duplicate faces", 1)    # the same: not again
    """
    h = hashlib.blake2b(digest_size=16)
    for a in arrays:
        a = np.ascontiguousarray(a)
        h.update(f"{a.dtype.str}{a.shape}".encode())
        if a.size:
            h.update(memoryview(a).cast("B"))
    key = (h.hexdigest(), topic)
    with _NOTED_LOCK:  # threads of a pool or a batch note repairs at once
        seen = key in _NOTED
        _NOTED[key] = None
        _NOTED.move_to_end(key)
        while len(_NOTED) > 64:
            _NOTED.popitem(last=False)
    if not seen:
        log.warning(message, *args)


def check_points(P, planar=True, min_points=4, what="the point cloud"):
    """Refuse, with a MeshError that names the problem, a point cloud no surface or point-cloud
    operator can be built on -- before Qhull, geometry-central or Open3D fail on it with their
    own messages (``QH6239 Qhull precision error``, ``GC_SAFETY_ASSERT FAILURE``, ...).

    Parameters
    ----------
    P : (n, 3) array_like
        The point positions.
    planar : bool
        Whether points in one plane are acceptable (a flat patch: robust point-cloud Laplacians
        take it; a reconstruction of a closed surface does not).
    min_points : int
        The fewest distinct points accepted (a k-nearest-neighbour operator needs ``k + 1``).
    what : str
        What to call the points in messages.

    Returns
    -------
    (n, 3) float64 ndarray
        The points, checked: finite, at least ``min_points`` distinct ones, not all coincident,
        not all on one line, and (``planar=False``) not all in one plane -- relative to the
        cloud's extent, at 1e-12.

    Examples
    --------
    >>> import numpy as np, o3dheat.geometry.mesh as m
    >>> m.check_points(np.random.default_rng(0).random((10, 3))).shape
    (10, 3)
    >>> m.check_points(np.c_[np.arange(10.0), np.zeros(10), np.zeros(10)])
    Traceback (most recent call last):
    ...
    o3dheat.errors.MeshError: the point cloud's 10 points lie on one line: no surface passes through them
    """
    try:
        P = np.asarray(P, dtype=np.float64)
    except (TypeError, ValueError) as e:
        raise MeshError(f"{what}: the points must be numbers ({e})") from None
    if P.ndim != 2 or P.shape[1] != 3:
        raise MeshError(f"{what}: the points must have shape (n, 3), got {P.shape}")
    if not np.all(np.isfinite(P)):
        raise MeshError(f"{what} has NaN or infinite coordinates")
    n = len(P)
    distinct = int(np.sum(first_copies(P) == np.arange(n))) if n else 0
    if distinct == 1 or (n and np.all(P == P[0])):
        raise MeshError(f"{what}'s {n} points all coincide: no surface passes through them")
    if distinct < min_points:
        raise MeshError(f"{what} has {distinct} distinct points ({n} in all): at least {min_points} are "
                        "needed")
    s = np.linalg.svd((P - P.mean(axis=0)) / max(float(np.max(np.ptp(P, axis=0))), np.finfo(float).tiny),
                      compute_uv=False)
    if s[1] <= 1e-12 * s[0]:
        raise MeshError(f"{what}'s {n} points lie on one line: no surface passes through them")
    if not planar and s[2] <= 1e-12 * s[0]:
        raise MeshError(f"{what}'s {n} points lie in one plane: a reconstruction needs points around a "
                        "volume (for a flat patch, use a point-cloud operator or triangulate it)")
    return P


def _shaped(mesh):
    """(V (n, 3) float64 copy, F (m, 3) int64 copy) with their shapes and types checked (the
    checks every function shares; contents -- finiteness, index range -- are checked by callers)."""
    pair = _pair(mesh)
    try:
        V = np.array(pair[0], dtype=np.float64, copy=True)
        F_in = np.asarray(pair[1])
    except (TypeError, ValueError) as e:
        raise MeshError(f"vertices and faces must be numeric arrays ({e})") from None
    if V.size == 0:
        V = V.reshape(0, 3)
    if V.ndim != 2 or V.shape[1] != 3:
        raise MeshError(f"vertices must have shape (n, 3), got {V.shape}")
    if F_in.size == 0:
        return V, np.zeros((0, 3), np.int64)
    if F_in.ndim != 2 or F_in.shape[1] != 3:
        raise MeshError(f"faces must have shape (m, 3) (triangles), got {F_in.shape}")
    if not (np.issubdtype(F_in.dtype, np.integer) or np.issubdtype(F_in.dtype, np.floating)):
        raise MeshError(f"face indices must be integers, got dtype {F_in.dtype}")
    if not np.issubdtype(F_in.dtype, np.integer):
        if not np.all(np.isfinite(F_in)) or np.any(F_in != np.round(F_in)):
            raise MeshError("face indices must be integers")
    return V, F_in.astype(np.int64, copy=True)


def as_arrays(mesh):
    """Return the vertices and faces of a mesh as checked numpy arrays.

    Parameters
    ----------
    mesh : o3d.t.geometry.TriangleMesh, o3d.geometry.TriangleMesh, (V, F) tuple or mesh-like
        The surface. ``V`` is ``(n, 3)`` real, ``F`` is ``(m, 3)`` integer (0-based). A mesh-like
        is any object with a ``mesh`` attribute holding one of these (:func:`mesh_of`): a
        :class:`Repaired`, a :class:`o3dheat.geometry.sampling.Resampled`...

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
    V, F = _shaped(mesh)
    if len(V) == 0:
        raise MeshError("the mesh is empty (no vertices)")
    if len(F) == 0:
        raise MeshError("the mesh has no faces: o3dheat needs a triangle mesh, not a point set")
    bad = ~np.all(np.isfinite(V), axis=1)
    if bad.any():
        raise MeshError(f"{int(bad.sum())} vertices have NaN or infinite coordinates "
                        f"(first: {int(np.flatnonzero(bad)[0])}); remove or fix them first")
    if F.min() < 0 or F.max() >= len(V):
        raise MeshError(f"face indices out of range: they must lie in [0, {len(V) - 1}], "
                        f"found [{int(F.min())}, {int(F.max())}]")
    extent = float(np.max(np.ptp(V, axis=0)))
    if extent > EXTENT_RANGE[1] or 0 < extent < EXTENT_RANGE[0]:
        raise MeshError(f"the mesh spans {extent:.3g} units: areas and eigenvalues (units², 1/units²) are "
                        f"not representable in float64 beyond [{EXTENT_RANGE[0]:g}, {EXTENT_RANGE[1]:g}]; "
                        "rescale it (results are scale covariant: K_t(αM) = K_{t/α²}(M))")
    return V, F


#: extents (largest side of the bounding box) o3dheat accepts; within it every computation is exact
#: up to rounding, geometry being evaluated at a power-of-two scale (:func:`unit_scale`)
EXTENT_RANGE = (1e-100, 1e100)


def face_areas(V, F):
    """Areas of the triangles.

    Parameters
    ----------
    V : (n, 3) float64 ndarray
        Vertex positions.
    F : (m, 3) int ndarray
        The triangles, as indices of their vertices.

    Returns
    -------
    (m,) float64 ndarray
        ``|t| = ||(v1 - v0) x (v2 - v0)|| / 2``, in squared units of ``V``.

    Examples
    --------
    >>> import numpy as np, o3dheat.geometry.mesh as m
    >>> m.face_areas(np.eye(3), np.array([[0, 1, 2]])).round(4)
    array([0.866])
    """
    from ._loops import double_areas

    s = unit_scale(V)
    V = V / s if s != 1.0 else V
    area = 0.5 * double_areas(V, F)
    return area * (s * s) if s != 1.0 else area


@dataclass
class _Cleaned:
    """What :func:`_clean` did to a mesh's faces: the one set of rules :func:`prepare` (every
    computation) applies and :func:`check_mesh` reports."""

    F: np.ndarray  # the faces used, in the caller's vertex numbering (welded copies replaced)
    rep: np.ndarray | None  # weld map (n,) or None when nothing was welded
    welded: int = 0  # referenced copies welded into an earlier one
    split: int = 0  # referenced vertices coincident with another, kept apart (see weld)
    degenerate: int = 0
    duplicate: int = 0
    zero_area: int = 0
    used: np.ndarray | None = None  # (n,) bool: vertices of the faces used
    unreferenced: int = 0  # input vertices in no face used (welded copies not counted)


def _clean(V, F, weld=True):
    """Weld, then drop degenerate, duplicate and zero-area faces, in this order (the rules of the
    module docstring), counting each. ``V`` must be finite, ``F`` in range."""
    n = len(V)
    rep, split = weld_copies(V, F) if weld else (None, 0)
    welded = 0 if rep is None else int(np.sum(rep != np.arange(n)))
    if welded:
        F = rep[F]
    else:
        rep = None
    c = _Cleaned(F, rep, welded, split)
    bad = degenerate(F)
    c.degenerate = int(bad.sum())
    F = F[~bad]
    if len(F):
        first = first_faces(F)
        c.duplicate = int(np.sum(~first))
        F = F[first]
    if len(F):
        zero = zero_area(V, F)
        c.zero_area = int(zero.sum())
        F = F[~zero]
    c.F = F
    c.used = np.zeros(n, bool)
    c.used[F.reshape(-1)] = True
    # after welding, the copies are referenced by no face: they are not "set aside", unless all
    # the faces of their welded vertex went
    c.unreferenced = int(n - c.used.sum() - welded)
    if welded:
        c.unreferenced += int(np.sum(~c.used[rep] & (rep != np.arange(n))))
    return c


@dataclass
class MeshReport:
    """What :func:`check_mesh` found. ``str(report)`` gives a readable summary.

    Attributes are counts (int) unless said otherwise; ``ok`` is True when every o3dheat function
    uses the mesh as it is, without any repair: nothing welded or dropped, and a 2-manifold
    (``manifold``: what topology needs; the FEM takes non-manifold meshes). The counts come from
    the rules :func:`prepare` applies (one function, ``_clean``): when duplicate vertices are
    welded (``welded_vertices``) or faces dropped (``used_faces`` are left), the edge, boundary,
    component, Euler characteristic, genus and non-manifold counts are those of the mesh every
    computation uses; the vertex and face counts are those of the input. ``split_vertices``:
    referenced vertices that coincide with another but stay apart (welding joins the copies a
    triangle soup has, not the vertices an indexed mesh keeps separate, as :func:`repair` makes).

    Examples
    --------
    >>> import open3d as o3d, o3dheat
    >>> report = o3dheat.check_mesh(o3d.t.geometry.TriangleMesh.create_sphere(1.0, 10))
    >>> report.ok, report.euler_characteristic, report.genus, report.boundary_loops
    (True, 2, 0.0, 0)
    """

    n_vertices: int
    n_faces: int
    degenerate_faces: int  # faces that repeat a vertex index
    zero_area_faces: int  # distinct corners but no area
    duplicate_faces: int
    unreferenced_vertices: int
    duplicate_vertices: int  # vertices sharing coordinates with an earlier one (any, referenced or not)
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
    welded_vertices: int = 0  # referenced duplicates welded into an earlier copy (0 with weld=False)
    used_faces: int = -1  # faces every computation uses (after the drops); -1: not counted
    split_vertices: int = 0  # referenced vertices coincident with another, kept apart by welding

    @property
    def manifold(self):
        """True when topology (critical points, persistence, level sets) accepts the mesh: faces
        left, no non-manifold edge or vertex (what :class:`o3dheat.topology.Surface` checks)."""
        return self.used_faces != 0 and not self.non_manifold_edges and not self.non_manifold_vertices

    @property
    def ok(self):
        """True when the check found no problem (``problems`` is empty)."""
        return not self.problems

    def __str__(self):
        g = "n/a" if self.genus is None else (f"{self.genus:g}")
        welded = f" ({self.n_vertices - self.welded_vertices} after welding)" if self.welded_vertices else ""
        used = (f" ({self.used_faces} used)" if 0 <= self.used_faces != self.n_faces else "")
        lines = [
            f"vertices: {self.n_vertices}{welded}   faces: {self.n_faces}{used}   area: {self.area:.6g}",
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


def check_mesh(mesh, weld=True):
    """Inspect a mesh and report everything that matters to the FEM operators.

    Unlike :func:`as_arrays` it never raises on a bad mesh (except when it cannot read one at
    all); it counts the problems instead. The mesh is cleaned by the very function
    :func:`prepare` uses (weld, then drop degenerate, duplicate and zero-area faces): the report
    describes the mesh that every computation uses, and its status names each repair and a
    non-manifold edge or vertex (which :func:`o3dheat.critical_points` refuses): ``ok`` is then
    False.

    Parameters
    ----------
    mesh : o3d.t.geometry.TriangleMesh, o3d.geometry.TriangleMesh or (V, F) tuple
        The mesh to inspect (not modified).
    weld : bool
        As for :func:`prepare`: False reports the mesh with its copies apart.

    Returns
    -------
    MeshReport
        Counts of degenerate, zero-area and duplicate faces, unreferenced and duplicate vertices,
        non-manifold edges and vertices, boundary loops, connected components, non-finite
        coordinates; the Euler characteristic ``V - E + F`` (of the referenced part) and the
        genus ``(2 c - chi - b) / 2`` (for a manifold mesh, with ``c`` components and ``b``
        boundary loops), all after welding; ``welded_vertices``.

    Examples
    --------
    >>> import numpy as np, open3d as o3d, o3dheat
    >>> r = o3dheat.check_mesh(o3d.t.geometry.TriangleMesh.create_torus())
    >>> r.euler_characteristic, r.genus, r.ok
    (0, 1.0, True)

    The same torus as a triangle soup (every face with its own three vertex copies, as read from
    an STL file):

    >>> V, F = o3dheat.as_arrays(o3d.t.geometry.TriangleMesh.create_torus())
    >>> r = o3dheat.check_mesh((V[F].reshape(-1, 3), np.arange(3 * len(F)).reshape(-1, 3)))
    >>> r.welded_vertices, r.components, r.genus, r.ok
    (3000, 1, 1.0, False)
    """
    V, F = _shaped(mesh)  # shapes and types as every function checks them; contents are counted
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
    dup_verts = int(np.sum(first_copies(V) != np.arange(n)))
    finite = np.all(np.isfinite(V), axis=1)
    Vf = np.where(finite[:, None], V, 0.0)
    # the very rules every computation applies (prepare), so that the counts below are those of
    # the mesh the computations use (a non-finite mesh is reported, not welded)
    c = _clean(Vf, F, weld=weld and not nonfinite)
    good = c.F
    E, counts = edges(good) if len(good) else (np.zeros((0, 2), int), np.zeros(0, int))
    nm_edges = int(np.sum(counts > 2))
    bE = E[counts == 1]
    loops = _boundary_loops(bE)
    nm_verts = non_manifold_vertices(good, n) if len(good) else 0
    if len(good):
        g = sp.coo_matrix((np.ones(len(E)), (E[:, 0], E[:, 1])), shape=(n, n))
        _, lab = connected_components(g, directed=False)
        components = len(np.unique(lab[np.unique(good)]))
    else:
        components = 0
    chi = int(c.used.sum() - len(E) + len(good)) if len(good) else 0
    genus = None
    if nm_edges == 0 and nm_verts == 0 and len(good):
        genus = (2 * components - chi - loops) / 2
    area = float(face_areas(Vf, good).sum()) if len(good) else 0.0
    if c.welded:
        apart = (f"; {c.split} coincident vertices kept apart (split: each is a vertex of its own, "
                 f"in the input as after welding)" if c.split else "")
        problems.append(f"welded {c.welded} duplicate vertices (exactly coincident coordinates) into "
                        f"{int(np.sum(c.used))}{apart}; the counts above are of the welded mesh")
    if c.degenerate:
        problems.append(f"{c.degenerate} degenerate faces (dropped)")
    if c.zero_area:
        problems.append(f"{c.zero_area} zero-area faces (dropped)")
    if c.duplicate:
        problems.append(f"{c.duplicate} duplicate faces (dropped)")
    if c.unreferenced:
        problems.append(f"{c.unreferenced} unreferenced vertices (set aside, value 0 in results)")
    if m and not len(good) and not nonfinite:
        problems.append("no face with a positive area is left: every computation refuses the mesh")
    if nm_edges or nm_verts:
        problems.append(f"not a 2-manifold ({nm_edges} non-manifold edges, {nm_verts} non-manifold "
                        "vertices): the FEM (spectrum, heat kernel) uses it, topology (critical points, "
                        "persistence) refuses it; o3dheat.repair(mesh) splits them")
    return MeshReport(n, int(m), c.degenerate, c.zero_area, c.duplicate, c.unreferenced, dup_verts,
                      nm_edges, nm_verts, int(len(bE)), loops, int(components), nonfinite, chi,
                      genus, area, problems, c.welded, int(len(good)), c.split)


@dataclass(frozen=True)
class Prepared:
    """A mesh ready for the FEM operators, and the way back to the caller's vertex numbering.

    Attributes
    ----------
    V : (r, 3) float64 ndarray
        The referenced, welded vertices.
    F : (m, 3) int64 ndarray
        Faces re-indexed into ``V``.
    keep : (r,) int64 ndarray
        ``keep[j]`` is the caller's index of vertex ``j`` (for a welded vertex: its first copy),
        so ``keep[F]`` is a face list in the caller's numbering.
    n_input : int
        Number of vertices of the caller's mesh.
    weld : (n_input,) int64 ndarray or None
        ``weld[i]``: the vertex of ``V`` that the caller's vertex ``i`` is (a copy of), -1 when
        it is unreferenced. None when no vertex was welded (then it is the inverse of ``keep``:
        see :attr:`vertex_map`).

    Notes
    -----
    With ``P`` the ``n_input x r`` matrix ``P[i, w[i]] = 1`` (:meth:`selection`) and ``D`` the
    diagonal of the multiplicities ``Pᵀ 1`` (:attr:`multiplicity`): :meth:`expand` is ``P X``,
    :meth:`restrict` is ``D⁻¹ Pᵀ f`` (the mean over the copies) and :meth:`expand_operator` is
    ``P D⁻¹ A D⁻¹ Pᵀ`` (see the module docstring for why).

    Examples
    --------
    Two triangles that share an edge through copies of its vertices (as in STL files):

    >>> import numpy as np, o3dheat.geometry.mesh as m
    >>> V = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0.]])
    >>> p = m.prepare((V, np.array([[0, 1, 2], [3, 4, 5]])))      # 3 and 5 copy 1 and 2
    >>> p.V.shape, p.F.tolist(), p.n_input
    ((4, 3), [[0, 1, 2], [1, 3, 2]], 6)
    >>> p.vertex_map.tolist(), p.multiplicity.tolist()
    ([0, 1, 2, 1, 3, 2], [1, 2, 2, 1])
    """

    V: np.ndarray
    F: np.ndarray
    keep: np.ndarray
    n_input: int
    weld: np.ndarray | None = None

    @property
    def vertex_map(self):
        """(n_input,) int64: the vertex of ``V`` of each input vertex, -1 where unreferenced."""
        if self.weld is not None:
            return self.weld
        w = np.full(self.n_input, -1, dtype=np.int64)
        w[self.keep] = np.arange(len(self.keep))
        return w

    @property
    def multiplicity(self):
        """(r,) int64: how many input vertices each vertex of ``V`` stands for (1 unless welded)."""
        if self.weld is None:
            return np.ones(len(self.keep), dtype=np.int64)
        w = self.weld
        return np.bincount(w[w >= 0], minlength=len(self.keep))

    def selection(self):
        """``P``, the ``(n_input, r)`` 0/1 sparse matrix with ``P[i, vertex_map[i]] = 1``.

        Examples
        --------
        >>> import numpy as np, o3dheat.geometry.mesh as m
        >>> V = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0.]])
        >>> p = m.prepare((V, np.array([[0, 1, 2], [3, 4, 5]])))
        >>> p.selection().toarray().astype(int).tolist()     # input vertex 3 is vertex 1 of V
        [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 1, 0, 0], [0, 0, 0, 1], [0, 0, 1, 0]]
        """
        w = self.vertex_map
        rows = np.flatnonzero(w >= 0)
        return sp.csc_matrix((np.ones(len(rows)), (rows, w[rows])), shape=(self.n_input, len(self.keep)))

    def expand(self, X):
        """Map per-vertex values (r, ...) back to the caller's n_input vertices: ``X[w]``, so the
        copies of a welded vertex get its value, and 0 at unreferenced vertices.

        Examples
        --------
        >>> import numpy as np, o3dheat.geometry.mesh as m
        >>> V = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0.]])
        >>> p = m.prepare((V, np.array([[0, 1, 2], [3, 4, 5]])))      # 3 and 5 copy 1 and 2
        >>> p.expand(np.array([10.0, 11, 12, 14])).tolist()
        [10.0, 11.0, 12.0, 11.0, 14.0, 12.0]
        """
        X = np.asarray(X)
        if self.weld is None:
            if len(self.keep) == self.n_input:
                return X
            out = np.zeros((self.n_input,) + X.shape[1:], dtype=X.dtype)
            out[self.keep] = X
            return out
        w = self.weld
        out = X[np.maximum(w, 0)]
        out[w < 0] = 0
        return out

    def restrict(self, f):
        """Per-vertex values of the caller's mesh (n_input, ...) on the vertices of ``V``: the mean
        over the copies of each welded vertex (the value itself when there is one copy).

        Examples
        --------
        >>> import numpy as np, o3dheat.geometry.mesh as m
        >>> V = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0.]])
        >>> p = m.prepare((V, np.array([[0, 1, 2], [3, 4, 5]])))
        >>> p.restrict(np.array([0.0, 1, 2, 3, 4, 5])).tolist()    # vertex 1: mean of 1 and 3
        [0.0, 2.0, 3.5, 4.0]
        """
        f = np.asarray(f)
        if self.weld is None:
            return f if len(self.keep) == self.n_input else f[self.keep]
        # the first copy's value plus the mean deviation of the copies from it: exact when the
        # copies agree (a field that came from expand comes back bit for bit)
        w = self.weld
        mean = sp.diags(1.0 / self.multiplicity) @ self.selection().T.tocsr()
        flat = f.reshape(self.n_input, -1).astype(np.result_type(f.dtype, np.float64))
        base = flat[self.keep]
        dev = flat - base[np.maximum(w, 0)]
        dev[w < 0] = 0.0
        return (base + mean @ dev).reshape((len(self.keep),) + f.shape[1:])

    def expand_operator(self, A):
        """An (r, r) operator on ``V`` as an (n_input, n_input) one: ``P D⁻¹ A D⁻¹ Pᵀ`` (``P A Pᵀ``
        when nothing was welded), in CSC. Its quadratic form on ``P x`` is that of ``A`` on ``x``.

        Examples
        --------
        >>> import numpy as np, scipy.sparse as sp, o3dheat.geometry.mesh as m
        >>> V = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0.]])
        >>> p = m.prepare((V, np.array([[0, 1, 2], [3, 4, 5]])))
        >>> A = sp.diags([1.0, 2.0, 3.0, 4.0])
        >>> x = np.array([1.0, -1.0, 2.0, 0.5])
        >>> Ai = p.expand_operator(A)
        >>> Ai.shape, bool(np.isclose(p.expand(x) @ Ai @ p.expand(x), x @ A @ x))
        ((6, 6), True)
        """
        P = self.selection()
        if self.weld is not None:
            P = P @ sp.diags(1.0 / self.multiplicity)
        return sp.csc_matrix(P @ A @ P.T)


def prepare(mesh, weld=True):
    """Convert and repair a mesh for the FEM operators (see the module docstring for the rules).

    Parameters
    ----------
    mesh : o3d.t.geometry.TriangleMesh, o3d.geometry.TriangleMesh or (V, F) tuple
        The mesh to convert (not modified).
    weld : bool
        Weld the referenced vertices with exactly equal coordinates (the default; logged as a
        warning with their number). False keeps them apart: each copy then lies on a boundary.

    Returns
    -------
    Prepared

    Raises
    ------
    MeshError
        When :func:`as_arrays` does, or when no face with positive area is left.

    Examples
    --------
    >>> import numpy as np, o3dheat.geometry.mesh as m
    >>> V = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [5, 5, 5.]])
    >>> p = m.prepare((V, np.array([[0, 1, 2]])))
    >>> p.keep.tolist(), p.n_input
    ([0, 1, 2], 4)

    Two triangles with their own vertex copies (an STL file): welded into 4 vertices.

    >>> V = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0.]])
    >>> p = m.prepare((V, np.array([[0, 1, 2], [3, 4, 5]])))
    >>> p.F.tolist(), p.keep.tolist(), p.weld.tolist()
    ([[0, 1, 2], [1, 3, 2]], [0, 1, 2, 4], [0, 1, 2, 1, 3, 2])
    """
    V, F = as_arrays(mesh)
    n = len(V)
    c = _clean(V, F, weld=weld)
    if c.welded:
        apart = (f"; {c.split} vertices coincide with another but are kept apart (split: a vertex of "
                 "its own each, as they are in the input)" if c.split else "")
        note_repair((V, F), "weld", "welded %d duplicate vertices (exactly coincident coordinates) into %d%s: "
                    "results are given per input vertex, each copy with the value of its welded vertex",
                    c.welded, len(np.unique(c.rep[F.reshape(-1)])), apart)
    for count, topic, what in ((c.degenerate, "degenerate", "degenerate faces (a vertex index repeated)"),
                               (c.duplicate, "duplicate", "duplicate faces"),
                               (c.zero_area, "zero-area", "zero-area faces")):
        if count:
            note_repair((V, F), topic, "dropping %d " + what, count)
    F = c.F
    if len(F) == 0:
        raise MeshError("no face with a positive area is left: the mesh is degenerate")
    if c.used.all():
        return Prepared(V, F, np.arange(n), n)
    keep = np.flatnonzero(c.used)
    if c.unreferenced:
        note_repair((V, F), "unreferenced", "%d unreferenced vertices set aside; they get the value 0 in every "
                    "result", c.unreferenced)
    remap = np.full(n, -1, dtype=np.int64)
    remap[keep] = np.arange(len(keep))
    return Prepared(V[keep], remap[F], keep, n, remap[c.rep] if c.welded else None)


# ------------------------------------------------------------------------------------- repair
@dataclass
class Repaired:
    """What :func:`repair` made of a mesh.

    Attributes
    ----------
    mesh : o3d.t.geometry.TriangleMesh
        The repaired mesh, with the input's vertex attributes carried over (each output vertex
        takes the values of its source vertex).
    source : (r,) int64 ndarray
        For each output vertex, the input vertex it comes from (a split vertex has several
        output copies with the same source).
    welded, dropped_faces, split_vertices, flipped_faces, removed_components : int
        What was done: duplicate vertices welded; degenerate, duplicate and zero-area faces
        dropped; extra vertex copies made to split non-manifold edges and vertices; faces flipped
        to orient each component consistently; small components removed (with their faces).
    orientable : bool
        False when some component is non-orientable (a Möbius band): left as it is.

    Examples
    --------
    >>> import numpy as np, o3dheat
    >>> V = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0.]])
    >>> r = o3dheat.repair((V, np.array([[0, 1, 2], [3, 4, 5], [0, 0, 1]])))
    >>> print(r)
    welded 2 duplicate vertices; dropped 1 degenerate/duplicate/zero-area faces
    >>> r.mesh.vertex.positions.shape, r.source.tolist()
    (SizeVector[4, 3], [0, 1, 2, 4])
    """

    mesh: object
    source: np.ndarray
    welded: int = 0
    dropped_faces: int = 0
    split_vertices: int = 0
    flipped_faces: int = 0
    removed_components: int = 0
    orientable: bool = True

    def __str__(self):
        done = [f"welded {self.welded} duplicate vertices" if self.welded else "",
                f"dropped {self.dropped_faces} degenerate/duplicate/zero-area faces" if self.dropped_faces else "",
                f"split {self.split_vertices} vertex copies off non-manifold edges and vertices"
                if self.split_vertices else "",
                f"flipped {self.flipped_faces} faces to a consistent orientation" if self.flipped_faces else "",
                f"removed {self.removed_components} small components" if self.removed_components else "",
                "" if self.orientable else "a component is not orientable (left as it is)"]
        done = [d for d in done if d]
        return "; ".join(done) if done else "nothing to repair"


def _split_fans(F, n):
    """Split non-manifold edges and vertices: faces meet only across edges with exactly two faces;
    every vertex gets one copy per fan of faces so connected. Returns (new faces, source vertex of
    each new vertex); a 2-manifold comes back unchanged (same numbering)."""
    m = len(F)
    k, lab = corner_components(m, *corner_pairs(F, n))
    flat = F.reshape(-1)
    src = np.empty(k, np.int64)
    src[lab] = flat
    first = np.full(k, 3 * m, np.int64)
    np.minimum.at(first, lab, np.arange(3 * m))
    rank = np.empty(k, np.int64)
    rank[np.lexsort((first, src))] = np.arange(k)  # numbered by source vertex, then first corner
    out = np.empty(k, np.int64)
    out[rank] = src
    return rank[lab].reshape(m, 3), out


def repair(mesh, weld=True, split=True, orient=True, min_component_faces=0):
    """Repair a mesh for o3dheat: weld duplicate vertices, drop degenerate, duplicate and
    zero-area faces and unreferenced vertices (the rules of :func:`prepare`), split non-manifold
    edges and vertices, orient every component consistently, and optionally drop small components.

    Splitting (the usual repair of scans): faces are joined only across edges with exactly two
    faces; an edge with three or more faces is cut (each of its faces keeps its own copy of the
    edge), and a vertex whose faces form several fans gets one copy per fan. The result is a
    2-manifold with boundary that every o3dheat function accepts. Orientation is Open3D's
    ``orient_triangles`` (breadth-first over the faces); a non-orientable component is left as it is
    and reported. The copies a split makes have their source's coordinates; o3dheat's welding
    (:func:`prepare`) joins coincident copies only across edges with exactly two faces, so it
    leaves them apart and every function sees the repaired mesh as it is (except in rare tangles
    of overlapping copies of faces: pass ``weld=False`` there).

    Parameters
    ----------
    mesh : Open3D mesh (tensor or legacy), (V, F) or a resampling
        The mesh to repair (not modified).
    weld, split, orient : bool
        Steps to run (all by default).
    min_component_faces : int
        Components with fewer faces are removed (0 keeps all).

    Returns
    -------
    Repaired
        ``.mesh`` (a new tensor mesh with the input's vertex attributes carried over), ``.source``
        (input vertex of each output vertex) and what was done (``str()`` says it in one line).

    Examples
    --------
    >>> import numpy as np, o3dheat
    >>> V = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1.]])
    >>> F = np.array([[0, 1, 2], [1, 0, 3], [0, 1, 4]])          # edge 0-1 has three faces
    >>> r = o3dheat.repair((V, F))
    >>> str(r), len(r.source), o3dheat.check_mesh(r.mesh).non_manifold_edges
    ('split 4 vertex copies off non-manifold edges and vertices', 9, 0)
    """
    import open3d as o3d

    from o3dheat import checks

    min_component_faces = checks.count(min_component_faces, "min_component_faces", minimum=0,
                                       maximum=np.iinfo(np.int64).max)
    mesh = mesh_of(mesh)  # a Repaired, a Resampled...: their mesh, with its attributes
    n_faces_in = len(as_arrays(mesh)[1])
    p = prepare(mesh, weld=weld)
    welded = 0 if p.weld is None else int(np.sum(p.weld >= 0) - len(p.keep))
    V, F, source = p.V, p.F, p.keep
    dropped = n_faces_in - len(F)
    split_count = 0
    if split:
        F, src = _split_fans(F, len(V))
        split_count = len(src) - len(V)
        V, source = V[src], source[src]
    flipped, orientable = 0, True
    if orient:
        legacy = o3d.geometry.TriangleMesh(o3d.utility.Vector3dVector(V),
                                           o3d.utility.Vector3iVector(F.astype(np.int32)))
        if legacy.is_edge_manifold(allow_boundary_edges=True):
            orientable = bool(legacy.orient_triangles())
            G = np.asarray(legacy.triangles, dtype=np.int64)
            if orientable:
                flipped = int(np.sum(np.any(G != F, axis=1)))
                F = G
        else:  # split=False on a non-manifold mesh: orientation is not defined
            orientable = False
    removed = 0
    if min_component_faces:
        from scipy.sparse.csgraph import connected_components as components

        e = np.r_[F[:, [0, 1]], F[:, [1, 2]]]
        _, lab = components(sp.coo_matrix((np.ones(len(e)), (e[:, 0], e[:, 1])), shape=(len(V),) * 2),
                            directed=False)
        per = np.bincount(lab[F[:, 0]])
        small = per < min_component_faces
        removed = int(np.sum(small & (per > 0)))
        F = F[~small[lab[F[:, 0]]]]
        used = np.zeros(len(V), bool)
        used[F.reshape(-1)] = True
        remap = np.cumsum(used) - 1
        V, source, F = V[used], source[used], remap[F]
        if len(F) == 0:
            raise MeshError(f"every component has fewer than {min_component_faces} faces: nothing is left")
    out = o3d.t.geometry.TriangleMesh()
    out.vertex.positions = o3d.core.Tensor(np.ascontiguousarray(V))
    out.triangle.indices = o3d.core.Tensor(np.ascontiguousarray(F))
    if isinstance(mesh, o3d.geometry.TriangleMesh):
        mesh = o3d.t.geometry.TriangleMesh.from_legacy(mesh)
    if isinstance(mesh, o3d.t.geometry.TriangleMesh):
        for key in mesh.vertex:
            if key != "positions":
                out.vertex[key] = o3d.core.Tensor(np.ascontiguousarray(mesh.vertex[key].numpy()[source]))
    result = Repaired(out, source, welded, dropped, split_count, flipped, removed, orientable)
    log.info("repair: %s", result)
    return result
