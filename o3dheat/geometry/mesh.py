"""Meshes as checked arrays: :func:`as_arrays`, :func:`mesh_of`, :func:`check_mesh` (a
:class:`MeshReport`), :func:`check_points`, :func:`face_areas`, :func:`note_repair`.

This module is the only one that knows about Open3D mesh types. Everything downstream works on
plain arrays: vertices ``V`` as ``(n, 3) float64`` and faces ``F`` as ``(m, 3) int64``.

Non-manifold edges or vertices are reported by :func:`check_mesh` (its status is then not ok)
but are valid input to the FEM: the linear FEM sums over every triangle at an edge. Topology
(:mod:`o3dheat.topology`) needs a 2-manifold and refuses them; it welds duplicate vertices the
same way.

Every function taking a mesh takes a mesh-like too: an object with a ``mesh`` attribute holding
an Open3D mesh or ``(V, F)`` (:func:`mesh_of`; :class:`o3dheat.geometry.repairs.Repaired`,
:class:`o3dheat.geometry.sampling.Resampled`).

The repairs every computation applies (welding, dropped faces) are those of
:func:`o3dheat.geometry.welding.prepare` (its module's Notes); :func:`check_mesh` counts them.
"""

from __future__ import annotations

import hashlib
import logging
import threading
from collections import OrderedDict
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

from o3dheat import checks
from o3dheat.errors import MeshError

from ._loops import double_areas
from ._tables import clean, edges, first_copies, non_manifold_vertices, unit_scale

if TYPE_CHECKING:  # o3dheat.typing imports Open3D (1.5 s), which arrays never need: for annotations only
    from numpy.typing import ArrayLike

    from o3dheat.typing import MeshLike

__all__ = ["as_arrays", "mesh_of", "check_points", "check_mesh", "MeshReport", "face_areas", "note_repair"]

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


def mesh_of(mesh: object) -> object:
    """The mesh an object stands for: the object itself when it is an Open3D mesh or a ``(V, F)``
    pair, else its ``mesh`` attribute (followed while it is another such object).

    This is the one mesh-like protocol of o3dheat: every function that takes a mesh (filters,
    :func:`o3dheat.eigensolve <o3dheat.spectral.spectrum.eigensolve>`, :func:`o3dheat.critical_points <o3dheat.topology.critical.critical_points>`, ...) takes any object with a
    ``mesh`` attribute holding an Open3D triangle mesh or a ``(V, F)`` pair -- a
    :class:`o3dheat.geometry.repairs.Repaired` (:func:`o3dheat.repair <o3dheat.geometry.repairs.repair>`), a
    :class:`o3dheat.geometry.sampling.Resampled`, or one of yours.
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


def note_repair(arrays: tuple[ArrayLike, ...], topic: str, message: str, *args: object) -> None:
    """Log a repair (a warning on the ``o3dheat`` logger: welded vertices, dropped faces...) once
    per geometry and ``topic`` ("weld", "degenerate", "duplicate", "zero-area", "unreferenced"):
    the same mesh goes through :func:`o3dheat.geometry.welding.prepare` for its spectrum and through
    :class:`o3dheat.topology.Surface <o3dheat.topology.surface.Surface>` for its critical points, and a chain of filters reads it at
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


def check_points(P: ArrayLike, planar: bool = True, min_points: int = 4, what: str = "the point cloud") -> np.ndarray:
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


def as_arrays(mesh: MeshLike) -> tuple[np.ndarray, np.ndarray]:
    """Return the vertices and faces of a mesh as checked numpy arrays.

    Parameters
    ----------
    mesh : o3d.t.geometry.TriangleMesh, o3d.geometry.TriangleMesh, (V, F) tuple or mesh-like
        The surface. ``V`` is ``(n, 3)`` real, ``F`` is ``(m, 3)`` integer (0-based). A mesh-like
        is any object with a ``mesh`` attribute holding one of these (:func:`mesh_of`): a
        :class:`o3dheat.geometry.repairs.Repaired`, a :class:`o3dheat.geometry.sampling.Resampled`...

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


def face_areas(V: np.ndarray, F: np.ndarray) -> np.ndarray:
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
    s = unit_scale(V)
    V = V / s if s != 1.0 else V
    area = 0.5 * double_areas(V, F)
    return area * (s * s) if s != 1.0 else area


@dataclass
class MeshReport:
    """What :func:`check_mesh` found. ``str(report)`` gives a readable summary.

    Attributes are counts (int) unless said otherwise; ``ok`` is True when every o3dheat function
    uses the mesh as it is, without any repair: nothing welded or dropped, and a 2-manifold
    (``manifold``: what topology needs; the FEM takes non-manifold meshes). The counts come from
    the rules :func:`o3dheat.geometry.welding.prepare` applies (one function, ``clean``): when duplicate vertices are
    welded (``welded_vertices``) or faces dropped (``used_faces`` are left), the edge, boundary,
    component, Euler characteristic, genus and non-manifold counts are those of the mesh every
    computation uses; the vertex and face counts are those of the input. ``split_vertices``:
    referenced vertices that coincide with another but stay apart (welding joins the copies a
    triangle soup has, not the vertices an indexed mesh keeps separate, as :func:`o3dheat.repair <o3dheat.geometry.repairs.repair>` makes).

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
    def manifold(self) -> bool:
        """True when topology (critical points, persistence, level sets) accepts the mesh: faces
        left, no non-manifold edge or vertex (what :class:`o3dheat.topology.Surface <o3dheat.topology.surface.Surface>` checks)."""
        return self.used_faces != 0 and not self.non_manifold_edges and not self.non_manifold_vertices

    @property
    def ok(self) -> bool:
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


def check_mesh(mesh: MeshLike, weld: bool = True) -> MeshReport:
    """Inspect a mesh and report everything that matters to the FEM operators.

    Unlike :func:`as_arrays` it never raises on a bad mesh (except when it cannot read one at
    all); it counts the problems instead. The mesh is cleaned by the very function
    :func:`o3dheat.geometry.welding.prepare` uses (weld, then drop degenerate, duplicate and zero-area faces): the report
    describes the mesh that every computation uses, and its status names each repair and a
    non-manifold edge or vertex (which :func:`o3dheat.critical_points <o3dheat.topology.critical.critical_points>` refuses): ``ok`` is then
    False.

    Parameters
    ----------
    mesh : o3d.t.geometry.TriangleMesh, o3d.geometry.TriangleMesh or (V, F) tuple
        The mesh to inspect (not modified).
    weld : bool
        As for :func:`o3dheat.geometry.welding.prepare`: False reports the mesh with its copies apart.

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
    c = clean(Vf, F, weld=weld and not nonfinite)
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
