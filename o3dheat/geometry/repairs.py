"""Repairs for o3dheat that change the mesh: :func:`repair` (weld, drop, split non-manifold edges
and vertices, orient, drop small components) and its :class:`Repaired`."""

from __future__ import annotations

import logging
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

from o3dheat import checks
from o3dheat.errors import MeshError

from ._tables import corner_components, corner_pairs
from .mesh import as_arrays, mesh_of
from .welding import prepare

if TYPE_CHECKING:  # o3dheat.typing imports Open3D (1.5 s), which arrays never need: for annotations only
    from o3dheat.typing import MeshLike

__all__ = ["repair", "Repaired"]

log = logging.getLogger("o3dheat")


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


def repair(mesh: MeshLike, weld: bool = True, split: bool = True, orient: bool = True,
           min_component_faces: int = 0) -> Repaired:
    """Repair a mesh for o3dheat: weld duplicate vertices, drop degenerate, duplicate and
    zero-area faces and unreferenced vertices (the rules of :func:`o3dheat.geometry.welding.prepare`), split non-manifold
    edges and vertices, orient every component consistently, and optionally drop small components.

    Splitting (the usual repair of scans): faces are joined only across edges with exactly two
    faces; an edge with three or more faces is cut (each of its faces keeps its own copy of the
    edge), and a vertex whose faces form several fans gets one copy per fan. The result is a
    2-manifold with boundary that every o3dheat function accepts. Orientation is Open3D's
    ``orient_triangles`` (breadth-first over the faces); a non-orientable component is left as it is
    and reported. The copies a split makes have their source's coordinates; o3dheat's welding
    (:func:`o3dheat.geometry.welding.prepare`) joins coincident copies only across edges with exactly two faces, so it
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
        e = np.r_[F[:, [0, 1]], F[:, [1, 2]]]
        _, lab = connected_components(sp.coo_matrix((np.ones(len(e)), (e[:, 0], e[:, 1])), shape=(len(V),) * 2),
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
