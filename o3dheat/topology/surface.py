"""The combinatorial surface of a triangle mesh, checked to be a 2-manifold: :class:`Surface`.

Build it once and pass it instead of the mesh to analyse many fields on one mesh
(:func:`o3dheat.topology.critical.critical_points`, :func:`o3dheat.topology.diagrams.persistence`, ...).

Notes
-----
* **The mesh** must be a 2-manifold, possibly with boundary and several components: every edge
  in at most two faces and every vertex with one fan of faces (:class:`~o3dheat.errors.MeshError`
  otherwise, with advice). Faces repeating a vertex and duplicate faces are dropped with a
  warning; vertices referenced by no face are not part of the surface and never critical.
* **Duplicate vertices** (referenced, exactly equal coordinates: STL files, triangle soups) are
  welded as for the FEM (:func:`o3dheat.geometry.welding.prepare`) when the mesh comes with coordinates
  (not by :meth:`Surface.from_faces`): the faces use the first copy of each vertex, so results
  are those of the welded mesh. Vertex indices (critical points, pairs) name that first copy; a
  field is averaged over the copies of each vertex; per-vertex outputs
  (:attr:`o3dheat.topology.critical.CriticalPoints.kind`) give every copy the value of its welded vertex.

**How it scales.** The loops over vertices, edges and faces are compiled (numba, ``nogil``) and
cached beside their module (``o3dheat.topology._loops``), so only the first call of an
installation compiles them (a few seconds). A :class:`Surface` holds the mesh's vertex adjacency
in link order (each vertex's neighbours in order around it), built once in O(m): the corners
bucketed by vertex (a counting sort), then each vertex's link walked, which checks its edges (at
most two faces) and its fans (one) too; from ``(V, F)`` arrays, their checks and the search for
duplicate vertices (a hash table of the coordinates) are one compiled pass each. About 0.1–0.2 µs
per vertex from the arrays, single-threaded. The edges (:attr:`Surface.E`, ...) are made on first
use. At most 2**31 − 2 vertices (vertex ids are int32 inside).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from numpy.typing import ArrayLike
from scipy.sparse.csgraph import connected_components

from o3dheat import checks
from o3dheat.errors import MeshError
from o3dheat.geometry import as_arrays, note_repair
from o3dheat.geometry._tables import degenerate, unique_rows, weld_map
from o3dheat.geometry.mesh import EXTENT_RANGE
from o3dheat.typing import FieldLike, MeshLike

from . import _loops

__all__ = ["Surface"]


class Surface:
    """The combinatorial surface of a mesh: faces, edges, boundary, checked to be a 2-manifold.

    Build it once and pass it instead of the mesh to analyse many fields on one mesh.

    Parameters
    ----------
    mesh : o3d.t.geometry.TriangleMesh, o3d.geometry.TriangleMesh, (V, F) tuple or Surface
        The triangle mesh (a Surface is returned as is by :meth:`of`).
    weld : bool
        Weld referenced vertices with exactly equal coordinates first (the default, logged as a
        warning; see the module docstring, Notes).

    Attributes
    ----------
    n : int
        Number of vertices of the mesh (including unreferenced ones).
    F : (m, 3) int64 ndarray
        The faces used (degenerate and duplicate faces dropped).
    E : (e, 2) int64 ndarray
        Unique edges, ``E[:, 0] < E[:, 1]``, in lexicographic order (made on first use, as the two
        below: critical points and persistence do not need them).
    boundary_edge : (e,) bool ndarray
    face_edges : (m, 3) int64 ndarray
        Edge index of the edge ``(F[t, s], F[t, s + 1])`` of each face.
    used, boundary : (n,) bool ndarray
        Vertices referenced by a face; vertices on the boundary.
    degree : (n,) int64 ndarray
        Number of neighbours.
    euler_characteristic : int
        ``V − E + F`` of the referenced part.
    representative : (n,) int64 ndarray or None
        After welding, the vertex standing for each vertex (its first copy; itself when it is not
        a duplicate); None when nothing was welded.

    Raises
    ------
    MeshError
        When an edge has more than two faces or a vertex more than one fan of faces, or for more
        than 2**31 − 2 vertices or 715,827,882 faces.

    Notes
    -----
    Built in O(m) by compiled loops (see the module docstring): about 0.15 s from ``(V, F)`` arrays
    at 1M vertices, single-threaded, their checks and the search for duplicate vertices included.
    It holds about 90 bytes per vertex of a closed mesh (faces, vertex adjacency, ...; the edge
    tables add about 100 once used); its construction from ``(V, F)`` peaks at about 170 bytes per
    vertex (copies of the input, the corners bucketed by vertex, the duplicates' hash table),
    beyond the input.

    Examples
    --------
    >>> import open3d as o3d, o3dheat
    >>> s = o3dheat.topology.Surface(o3d.t.geometry.TriangleMesh.create_torus())
    >>> s.euler_characteristic, int(s.boundary.sum())
    (0, 0)
    """

    def __init__(self, mesh: MeshLike | Surface, weld: bool = True) -> None:
        V, F, dup = _plain(mesh)
        if V is None:
            V, F = as_arrays(mesh)
        self.V = V
        self.representative = None
        given = (V, F)  # what repairs are noted against (once per mesh, with prepare's: note_repair)
        if weld and dup is not False:
            rep = weld_map(V, F)
            welded = int(np.sum(rep != np.arange(len(V))))
            if welded:
                note_repair(given, "weld", "welded %d duplicate vertices (exactly coincident coordinates): the "
                            "faces use the first copy of each vertex", welded)
                self.representative, F = rep, rep[F]
        self._build(len(V), F, given)

    @classmethod
    def of(cls, mesh: MeshLike | Surface) -> Surface:
        """``mesh`` itself when it is a Surface, otherwise ``Surface(mesh)``.

        Examples
        --------
        >>> import open3d as o3d
        >>> from o3dheat.topology import Surface
        >>> s = Surface.of(o3d.t.geometry.TriangleMesh.create_torus())
        >>> Surface.of(s) is s, s.components
        (True, 1)
        """
        return mesh if isinstance(mesh, cls) else cls(mesh)

    @classmethod
    def from_faces(cls, n: int, F: ArrayLike, V: ArrayLike | None = None) -> Surface:
        """A Surface from a vertex count and faces (no coordinates needed; no welding).

        Examples
        --------
        Two triangles sharing an edge, and a vertex no face uses:

        >>> from o3dheat.topology import Surface
        >>> s = Surface.from_faces(5, [[0, 1, 2], [0, 2, 3]])
        >>> s.euler_characteristic, s.used.tolist(), int(s.boundary_edge.sum())
        (1, [True, True, True, True, False], 4)
        """
        self = cls.__new__(cls)
        self.V = V
        self.representative = None
        F = np.asarray(F, dtype=np.int64).reshape(-1, 3)
        if len(F) == 0:
            raise MeshError("the mesh has no faces")
        self._build(int(n), F, (F,))
        return self

    def _build(self, n: int, F: np.ndarray, given: tuple) -> None:
        if n >= 2**31 - 1:
            raise MeshError(f"{n} vertices: topology handles at most 2**31 - 2 vertices")
        F = np.ascontiguousarray(F, dtype=np.int64)
        links = _links
        tables = links(F, n) if 3 * len(F) < 2**31 else (2,)  # too many: refused once the degenerate are dropped
        if tables[0] == 1:
            raise MeshError(f"face indices out of range [0, {n - 1}]")
        if tables[0] == 2:
            bad = degenerate(F)
            if bad.any():
                note_repair(given, "degenerate", "dropping %d degenerate faces (a vertex index repeated)",
                            int(bad.sum()))
                F = np.ascontiguousarray(F[~bad])
            if len(F) == 0:
                raise MeshError("no face is left once the degenerate ones are dropped")
            if 3 * len(F) >= 2**31:
                raise MeshError(f"{len(F)} faces: topology handles at most {(2**31 - 1) // 3} faces")
            tables = links(F, n)
        if tables[5]:  # duplicate faces are one cause: drop them, then look again
            _, first = unique_rows(np.sort(F, axis=1), return_index=True)
            if len(first) < len(F):
                note_repair(given, "duplicate", "dropping %d duplicate faces", len(F) - len(first))
                F = np.ascontiguousarray(F[np.sort(first)])
                tables = links(F, n)
        _, ptr, adj, boundary, ne, bad_edges, bad_fans = tables
        if bad_edges:
            raise MeshError(f"{bad_edges} edges have more than two faces (non-manifold): "
                            "topology needs a 2-manifold: repair the mesh first with o3dheat.repair(mesh) "
                            "(or `o3dheat repair IN OUT`), which splits such edges")
        if bad_fans:
            raise MeshError(f"{bad_fans} vertices are non-manifold (their faces form several fans): topology "
                            "needs a 2-manifold: repair the mesh first with o3dheat.repair(mesh) (or "
                            "`o3dheat repair IN OUT`), which gives each fan its own vertex")
        self.n = n
        self.F = F
        self.degree = np.diff(ptr)
        self.used = self.degree > 0
        self.boundary = boundary
        self.euler_characteristic = int(np.count_nonzero(self.used) - ne + len(F))
        self._ptr, self._adj = ptr, adj  # the neighbours of vertex v: adj[ptr[v]:ptr[v + 1]], in link order

    def _edge_tables(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        tables = self.__dict__.get("_edges")
        if tables is None:  # on first use (level sets, tracking): persistence does not need them
            E, counts, face_edges = _loops.kernel("edge_tables")(self.F, self._ptr, self._adj)
            tables = self._edges = (E, counts == 1, face_edges.reshape(-1, 3))
        return tables

    @property
    def E(self) -> np.ndarray:
        """(e, 2) int64: the unique edges, ``E[:, 0] < E[:, 1]``, in lexicographic order (made on first use)."""
        return self._edge_tables()[0]

    @property
    def boundary_edge(self) -> np.ndarray:
        """(e,) bool: the edges of :attr:`E` with one face (made on first use)."""
        return self._edge_tables()[1]

    @property
    def face_edges(self) -> np.ndarray:
        """(m, 3) int64: the edge (in :attr:`E`) of the edge ``(F[t, s], F[t, s + 1])`` of each face (made on first use)."""
        return self._edge_tables()[2]

    @property
    def adjacency(self) -> tuple[np.ndarray, np.ndarray]:
        """``(ptr, adj)``: the neighbours of vertex ``v`` are ``adj[ptr[v]:ptr[v + 1]]`` (CSR), in
        the order of its link: consecutive ones span a face with ``v``, and so do the last and the
        first when ``v`` is not on the boundary (its lower link's arcs are runs of this list).

        Examples
        --------
        >>> import open3d as o3d
        >>> from o3dheat.topology import Surface
        >>> ptr, adj = Surface(o3d.t.geometry.TriangleMesh.create_torus()).adjacency
        >>> int(ptr[1] - ptr[0])
        6
        """
        return self._ptr, self._adj

    @property
    def components(self) -> int:
        """Number of connected components (of the referenced vertices)."""
        g = sp.csr_matrix((np.ones(len(self._adj), np.int8), self._adj, self._ptr), shape=(self.n, self.n))
        _, lab = connected_components(g, directed=False)
        return int(len(np.unique(lab[self.used])))

    def field(self, f: FieldLike, name: str = "f") -> np.ndarray:
        """``f`` as a checked (n,) float64 array (MeshError on a wrong shape or non-finite values).

        Examples
        --------
        >>> import open3d as o3d, o3dheat
        >>> from o3dheat.topology import Surface
        >>> m = o3d.t.geometry.TriangleMesh.create_torus()
        >>> s = Surface(m)
        >>> s.field(m.vertex.positions[:, 0]).dtype           # an Open3D tensor is read too
        dtype('float64')
        >>> s.field([1.0, 2.0])
        Traceback (most recent call last):
        ...
        o3dheat.errors.MeshError: f must have shape (600,) or (600, c) (one value per vertex), got (2,)
        """
        arr = checks.field(f, self.n, name)
        if arr.ndim == 2 and arr.shape[1] == 1:
            arr = arr[:, 0]
        if arr.ndim != 1:
            raise MeshError(f"{name} must have one value per vertex, shape ({self.n},), got {arr.shape}")
        rep = self.representative
        if rep is not None:  # welded: the mean over the copies of each vertex, on every copy, as
            # the first copy's value plus the mean deviation (exact when the copies agree)
            dev = np.bincount(rep, weights=arr - arr[rep], minlength=self.n)
            arr = arr[rep] + (dev / np.bincount(rep, minlength=self.n).clip(1))[rep]
        return arr


def _plain(mesh):
    """``(V, F, dup)`` as :func:`~o3dheat.geometry.mesh.as_arrays` makes them (copies, checked) for
    a tuple of two numpy arrays of the usual types, in one compiled pass over each
    (``_loops.checked_copy``), and whether two referenced vertices have exactly the same coordinates
    (``dup``: whether welding has anything to do; a hash table, ``_loops.duplicates``);
    ``(None, None, None)`` otherwise, and for anything as_arrays would refuse (it says why)."""
    if not (type(mesh) is tuple and len(mesh) == 2 and all(type(a) is np.ndarray for a in mesh)):
        return None, None, None
    V, F = mesh
    if not (V.dtype == np.float64 and V.ndim == 2 and V.shape[1] == 3 and len(V) and F.ndim == 2
            and F.shape[1] == 3 and len(F) and F.dtype.kind in "iu" and F.dtype.itemsize <= 8):
        return None, None, None
    V, n = np.array(V, dtype=np.float64, copy=True), len(V)
    Fc, used = np.empty((len(F), 3), np.int64), np.zeros(n, np.bool_)
    if not _loops.kernel("checked_copy")(V, np.ascontiguousarray(F, dtype=np.int64), *EXTENT_RANGE, Fc, used):
        return None, None, None
    size = 1 << max(int(2 * n - 1).bit_length(), 1)  # a power of two, at least 2n
    return V, Fc, _loops.kernel("duplicates")(V, used, np.full(size, -1, np.int32))


def _links(F, n):
    """``_loops.links`` (the adjacency in link order and its checks) on arrays numpy allocates:
    ``status``, ``ptr``, ``adj``, ``boundary``, edges, edges with more than two faces, vertices
    with several fans."""
    m = len(F)
    start, link = np.zeros(n + 2, np.int64), np.empty(6 * m, np.int32)
    ptr, adj, boundary = np.empty(n + 1, np.int64), np.empty(3 * m + n, np.int32), np.zeros(n, np.bool_)
    status, q, ne, bad_edges, bad_fans = _loops.kernel("links")(F, n, start, link, ptr, adj, boundary,
                                                                 np.full(n, -1, np.int32))
    return status, ptr, adj[:q], boundary, ne, bad_edges, bad_fans
