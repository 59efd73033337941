"""PL critical points of a per-vertex field on a triangle mesh (§3.1 of the paper): :func:`critical_points`.

It returns :class:`CriticalPoints` (kinds :data:`REGULAR`, :data:`MINIMUM`, :data:`SADDLE`,
:data:`MAXIMUM`); :func:`warm_up` loads the topology's compiled loops. A per-vertex field ``f`` is
extended linearly over the triangles. Everything here is combinatorial: it depends on the order of
the values, not on the geometry.

Notes
-----
Conventions (each one is tested):

* **Simulation of simplicity.** Vertices are ordered by ``(f, vertex index)``: of two equal
  values, the vertex with the smaller index counts as lower. Every field then behaves as a
  generic (Morse) one, so the Morse count ``M − Σ multiplicity + m`` equals the Euler
  characteristic of the mesh for every input, plateaus and constant fields included. A constant
  field is accepted (with a logged warning): its critical points are those of the vertex order.
* **Banchoff's classification by the lower link.** The lower link of a vertex is the part of its
  link (the cycle of neighbours, a path on the boundary) spanned by lower vertices. Empty: a
  minimum. The whole cycle of an interior vertex: a maximum. ``k >= 2`` arcs: a saddle of
  multiplicity ``k − 1`` (``k = 3``: a monkey saddle). Otherwise (one arc): regular.
* **Boundary vertices** follow the same rule with a path as link. So a boundary vertex is a
  minimum when all its neighbours are higher, a saddle when its lower neighbours form ``k >= 2``
  runs along the path, and regular otherwise, *including when all its neighbours are lower*: a
  boundary maximum does not change the topology of the sublevel sets, and the index
  ``1 − χ(lower link)`` is 0 there. This is the rule that makes ``M − s + m = χ`` hold on
  surfaces with boundary (a disk: χ = 1).
* **The mesh** must be a 2-manifold; duplicate vertices are welded: see
  :mod:`o3dheat.topology.surface`.

**How it scales.** A field costs one pass over the vertex adjacency and one over the faces
(compiled: ``o3dheat.topology._loops``; no sort of the vertices), once the :class:`~o3dheat.topology.surface.Surface` is
built.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np

from o3dheat._jit import any_compiled
from o3dheat.typing import FieldLike, MeshLike

from . import _loops
from .diagrams import persistence
from .surface import Surface

__all__ = ["CriticalPoints", "critical_points", "REGULAR", "MINIMUM", "SADDLE", "MAXIMUM", "warm_up",
           "compiled_in_this_process"]

log = logging.getLogger("o3dheat")

#: the kinds of vertex (:attr:`CriticalPoints.kind`)
REGULAR, MINIMUM, SADDLE, MAXIMUM = 0, 1, 2, 3


@dataclass(frozen=True)
class CriticalPoints:
    """PL critical points of a field (see the module docstring for the rules).

    Attributes
    ----------
    minima, saddles, maxima : int64 ndarray
        Vertex indices, ascending.
    saddle_multiplicity : int64 ndarray
        Same length as ``saddles``: ``k − 1`` for a lower link of ``k`` arcs (monkey saddle: 2).
    n : int
        Number of vertices of the mesh.
    representative : (n,) int64 ndarray or None
        :attr:`~o3dheat.topology.surface.Surface.representative` of the mesh (duplicate vertices welded), else None.

    Examples
    --------
    The height across an upright torus: one minimum, two saddles, one maximum.

    >>> import open3d as o3d, o3dheat
    >>> m = o3d.t.geometry.TriangleMesh.create_torus()
    >>> cp = o3dheat.critical_points(m, m.vertex.positions.numpy()[:, 0])
    >>> cp
    CriticalPoints(minima=1, saddles=2, maxima=1, euler_characteristic=0)
    >>> cp.counts, cp.euler_characteristic, cp.kind.shape, int((cp.kind == 2).sum())
    ((1, 2, 1), 0, (600,), 2)
    """

    minima: np.ndarray
    saddles: np.ndarray
    saddle_multiplicity: np.ndarray
    maxima: np.ndarray
    n: int
    representative: np.ndarray | None = None

    @property
    def euler_characteristic(self) -> int:
        """``M − Σ multiplicity + m``: equals the Euler characteristic of the mesh."""
        return int(len(self.maxima) - self.saddle_multiplicity.sum() + len(self.minima))

    @property
    def counts(self) -> tuple[int, int, int]:
        """``(minima, saddles counted with multiplicity, maxima)``."""
        return (len(self.minima), int(self.saddle_multiplicity.sum()), len(self.maxima))

    @property
    def kind(self) -> np.ndarray:
        """(n,) int8 per vertex: 0 regular, 1 minimum, 2 saddle, 3 maximum (the copies of a welded
        duplicate vertex: the kind of their first copy)."""
        out = np.zeros(self.n, np.int8)
        out[self.minima] = MINIMUM
        out[self.saddles] = SADDLE
        out[self.maxima] = MAXIMUM
        return out if self.representative is None else out[self.representative]

    def __len__(self):
        """Number of critical vertices (a saddle of multiplicity 2 is one vertex; ``sum(counts)``
        counts it twice, as the Morse relation ``M − s + m = χ`` does).

        Examples
        --------
        >>> import open3d as o3d, o3dheat
        >>> m = o3d.t.geometry.TriangleMesh.create_torus()
        >>> len(o3dheat.critical_points(m, m.vertex.positions.numpy()[:, 0]))
        4
        """
        return len(self.minima) + len(self.saddles) + len(self.maxima)

    def same_as(self, other: CriticalPoints) -> bool:
        """True when both have the same minima, saddles (with multiplicities) and maxima.

        Examples
        --------
        >>> import open3d as o3d, o3dheat
        >>> m = o3d.t.geometry.TriangleMesh.create_torus()
        >>> x = m.vertex.positions.numpy()[:, 0]
        >>> o3dheat.critical_points(m, x).same_as(o3dheat.critical_points(m, 2 * x + 1))
        True
        """
        return (np.array_equal(self.minima, other.minima) and np.array_equal(self.maxima, other.maxima)
                and np.array_equal(self.saddles, other.saddles)
                and np.array_equal(self.saddle_multiplicity, other.saddle_multiplicity))

    def __repr__(self):
        m, s, M = self.counts
        return f"CriticalPoints(minima={m}, saddles={s}, maxima={M}, euler_characteristic={m - s + M})"


def critical_points(mesh: MeshLike | Surface, f: FieldLike) -> CriticalPoints:
    """PL critical points of a per-vertex field (Banchoff's lower-link classification).

    Parameters
    ----------
    mesh : o3d.t.geometry.TriangleMesh, o3d.geometry.TriangleMesh, (V, F) tuple or Surface
        A 2-manifold triangle mesh, possibly with boundary and several components.
    f : (n,) array_like
        One finite value per vertex.

    Returns
    -------
    CriticalPoints
        ``euler_characteristic`` (``M − Σ multiplicity + m``) equals χ of the mesh for every field.

    Raises
    ------
    MeshError
        Non-manifold mesh, wrong length, NaN or infinite values.

    Notes
    -----
    Equal values are ordered by vertex index (simulation of simplicity). On the boundary a vertex
    whose neighbours are all lower is regular (see the module docstring).

    Cost: O(m), one pass over the vertex adjacency and one over the faces (compiled; no sort).
    Build the :class:`~o3dheat.topology.surface.Surface` once to analyse many fields: from
    ``(V, F)`` each call builds it again (0.3–0.7 s at 1M vertices, against 0.02–0.04 s for the
    field itself). Memory beyond the Surface and the field: about 25 bytes per vertex at the peak
    (measured at 0.1M, 1M and 10M vertices by ``scripts/bench_topology.py``).

    Examples
    --------
    >>> import open3d as o3d, o3dheat
    >>> mesh = o3d.t.geometry.TriangleMesh.create_torus(1.0, 0.4, 40, 20)
    >>> mesh = mesh.rotate(o3d.core.Tensor(o3d.geometry.get_rotation_matrix_from_xyz((1.5708, 0, 0))),
    ...                    o3d.core.Tensor([0.0, 0.0, 0.0]))     # axis horizontal: stand it upright
    >>> cp = o3dheat.critical_points(mesh, mesh.vertex.positions.numpy()[:, 2] )  # height
    >>> cp.counts, cp.euler_characteristic
    ((1, 2, 1), 0)
    """
    S = Surface.of(mesh)
    f = S.field(f)
    _loops.warn_constant(f, S)
    kind, mult, crit, _, _ = _loops.classified(S, f)
    kc = kind[crit]
    saddles = crit[kc == SADDLE]
    return CriticalPoints(crit[kc == MINIMUM], saddles, mult[saddles].astype(np.int64),
                          crit[kc == MAXIMUM], S.n, S.representative)


def warm_up() -> None:
    """Load the topology's compiled loops now (or compile them: the first call of an installation,
    or after a change of the source), by finding the critical points and persistence of a small
    field, so that the first real call does not pay it: about 0.3 s per process from the cache.
    Each Dask worker of o3dheat's studies and batches calls it at start
    (:func:`o3dheat.pipelines.cluster.register_warm_up`), like pymeshlab's first call.

    Examples
    --------
    >>> import o3dheat.topology as T
    >>> T.warm_up()
    """
    import open3d as o3d

    m = o3d.geometry.TriangleMesh.create_sphere(1.0, 6)
    V, F = np.asarray(m.vertices), np.asarray(m.triangles, dtype=np.int64)
    S = Surface((V, F))  # the checks of (V, F) arrays are compiled loops too
    f = V[:, 2] + 0.1 * V[:, 0]
    critical_points(S, f)
    persistence(S, f)


def compiled_in_this_process() -> bool:
    """Whether this process compiled any of the topology's loops (a first call of an installation,
    or after a change of the source: a few seconds once) rather than loading them from the cache.

    Examples
    --------
    >>> import o3dheat.topology as T
    >>> isinstance(T.compiled_in_this_process(), bool)
    True
    """
    return any_compiled(_loops.__name__)
