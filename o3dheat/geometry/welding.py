"""The mesh every computation uses: :func:`prepare` welds duplicate vertices and drops the faces
the FEM cannot use; its :class:`Prepared` maps results back to the caller's vertices.

Notes
-----
Repairs applied before any FEM computation (:func:`prepare`), each logged as a warning:

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
of faces each (a pinched vertex of a triangle soup, the copies :func:`o3dheat.repair <o3dheat.geometry.repairs.repair>` makes) stay apart,
and the weld's warning and :func:`o3dheat.geometry.mesh.check_mesh` (``split_vertices``) say how many. A soup cannot
tell one vertex with two fans from two coincident vertices with a fan each; an indexed file
(OBJ, PLY) can, and is taken as it is.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
import scipy.sparse as sp

from o3dheat.errors import MeshError

from ._tables import clean
from .mesh import as_arrays, note_repair

if TYPE_CHECKING:  # o3dheat.typing imports Open3D (1.5 s), which arrays never need: for annotations only
    from numpy.typing import ArrayLike

    from o3dheat.typing import MeshLike

__all__ = ["prepare", "Prepared"]


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
    ``P D⁻¹ A D⁻¹ Pᵀ`` (see the module's Notes for why).

    Examples
    --------
    Two triangles that share an edge through copies of its vertices (as in STL files):

    >>> import numpy as np, o3dheat.geometry.welding as m
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
    def vertex_map(self) -> np.ndarray:
        """(n_input,) int64: the vertex of ``V`` of each input vertex, -1 where unreferenced."""
        if self.weld is not None:
            return self.weld
        w = np.full(self.n_input, -1, dtype=np.int64)
        w[self.keep] = np.arange(len(self.keep))
        return w

    @property
    def multiplicity(self) -> np.ndarray:
        """(r,) int64: how many input vertices each vertex of ``V`` stands for (1 unless welded)."""
        if self.weld is None:
            return np.ones(len(self.keep), dtype=np.int64)
        w = self.weld
        return np.bincount(w[w >= 0], minlength=len(self.keep))

    def selection(self) -> sp.csc_matrix:
        """``P``, the ``(n_input, r)`` 0/1 sparse matrix with ``P[i, vertex_map[i]] = 1``.

        Examples
        --------
        >>> import numpy as np, o3dheat.geometry.welding as m
        >>> V = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0.]])
        >>> p = m.prepare((V, np.array([[0, 1, 2], [3, 4, 5]])))
        >>> p.selection().toarray().astype(int).tolist()     # input vertex 3 is vertex 1 of V
        [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 1, 0, 0], [0, 0, 0, 1], [0, 0, 1, 0]]
        """
        w = self.vertex_map
        rows = np.flatnonzero(w >= 0)
        return sp.csc_matrix((np.ones(len(rows)), (rows, w[rows])), shape=(self.n_input, len(self.keep)))

    def expand(self, X: ArrayLike) -> np.ndarray:
        """Map per-vertex values (r, ...) back to the caller's n_input vertices: ``X[w]``, so the
        copies of a welded vertex get its value, and 0 at unreferenced vertices.

        Examples
        --------
        >>> import numpy as np, o3dheat.geometry.welding as m
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

    def restrict(self, f: ArrayLike) -> np.ndarray:
        """Per-vertex values of the caller's mesh (n_input, ...) on the vertices of ``V``: the mean
        over the copies of each welded vertex (the value itself when there is one copy).

        Examples
        --------
        >>> import numpy as np, o3dheat.geometry.welding as m
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

    def expand_operator(self, A: sp.spmatrix) -> sp.csc_matrix:
        """An (r, r) operator on ``V`` as an (n_input, n_input) one: ``P D⁻¹ A D⁻¹ Pᵀ`` (``P A Pᵀ``
        when nothing was welded), in CSC. Its quadratic form on ``P x`` is that of ``A`` on ``x``.

        Examples
        --------
        >>> import numpy as np, scipy.sparse as sp, o3dheat.geometry.welding as m
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


def prepare(mesh: MeshLike, weld: bool = True) -> Prepared:
    """Convert and repair a mesh for the FEM operators (the rules in the module's Notes).

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
        When :func:`o3dheat.geometry.mesh.as_arrays` does, or when no face with positive area is left.

    Examples
    --------
    >>> import numpy as np, o3dheat.geometry.welding as m
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
    c = clean(V, F, weld=weld)
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
