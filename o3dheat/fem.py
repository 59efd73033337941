"""Linear-FEM operators on triangle meshes: cotangent stiffness, consistent and lumped mass,
Voronoi (mixed) areas.

Conventions (the paper's eq. (3), sign flipped so that L is positive semi-definite):

* ``L[i, j] = -(cot a_ij + cot b_ij) / 2`` for an edge ``ij`` (one cotangent on a boundary edge),
  ``L[i, i] = -sum_j L[i, j]``: symmetric, rows sum to 0, eigenvalues >= 0. ``L`` does not change
  when the mesh is scaled.
* ``B[i, j] = (|t_r| + |t_s|) / 12`` for an edge shared by triangles ``t_r, t_s``,
  ``B[i, i] = sum_{t ∋ i} |t| / 6``: the Gram matrix of the hat functions, symmetric positive
  definite, ``1ᵀ B 1`` = surface area; it scales with the square of the mesh size.
* lumped mass: ``diag(B 1)`` (a third of the area of the triangles at a vertex);
  Voronoi mass: ``diag(a)`` with the mixed Voronoi areas ``a`` of Meyer et al. (2003).

All functions take ``V (n, 3) float64`` and ``F (m, 3) int`` arrays (see :func:`o3dheat.as_arrays`)
and return ``scipy.sparse.csc_matrix`` of shape ``(n, n)``, float64.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from .errors import MeshError
from .mesh import _edges, face_areas, unit_scale

__all__ = ["stiffness_matrix", "mass_matrix", "voronoi_areas", "operators", "mean_curvature", "gaussian_curvature",
           "MASS_KINDS", "check_mass_kind"]

#: mass kind -> what the matrix is: the one definition of the masses of ``L x = λ B x``, used by
#: :func:`o3dheat.eigensolve`, :func:`o3dheat.diffuse`, the kernel variants
#: (:data:`o3dheat.kernel.VARIANTS` names a mass of this table) and the command (``--mass``)
MASS_KINDS = {
    "consistent": "the paper's consistent FEM mass B, B_rs = (|t_r| + |t_s|)/12, B_ii = Σ|t|/6",
    "lumped": "diag(B 1), the row sums of B: a third of the area of the triangles at each vertex",
    "voronoi": "diag(a), the mixed Voronoi areas a of Meyer et al. (2003)",
    "identity": "I, the paper's 'B := I' (eigenpairs of L x = λ x)",
}


def check_mass_kind(kind):
    """``kind`` if it is a key of :data:`MASS_KINDS`, else a :class:`~o3dheat.MeshError` listing them.

    Examples
    --------
    >>> from o3dheat.fem import check_mass_kind
    >>> check_mass_kind("lumped")
    'lumped'
    >>> check_mass_kind("area")
    Traceback (most recent call last):
    ...
    o3dheat.errors.MeshError: unknown mass kind 'area': use one of consistent, lumped, voronoi, identity
    """
    if not isinstance(kind, str) or kind not in MASS_KINDS:
        raise MeshError(f"unknown mass kind {kind!r}: use one of {', '.join(MASS_KINDS)}")
    return kind


def _corner_geometry(V, F):
    """Per-face double areas and the cotangent at each corner (m, 3)."""
    V = np.asarray(V, dtype=np.float64)
    F = np.asarray(F, dtype=np.int64)
    s = unit_scale(V)  # computed at unit scale (exact power of two), scaled back below
    if s != 1.0:
        V = V / s
    p = [V[F[:, i]] for i in range(3)]
    # edge opposite corner i: e_i = p[i+2] - p[i+1]
    e = [p[2] - p[1], p[0] - p[2], p[1] - p[0]]
    dbl = np.linalg.norm(np.cross(e[0], e[1]), axis=1)  # 2 |t|
    if np.any(dbl <= 0):
        raise MeshError(f"{int(np.sum(dbl <= 0))} faces have zero area: repair the mesh first "
                        "(o3dheat.mesh.prepare drops them)")
    # cot at corner i = <a, b> / |a x b|, a, b the edges leaving corner i = -e_{i+2}, e_{i+1}
    cot = np.stack([-np.einsum("ij,ij->i", e[(i + 2) % 3], e[(i + 1) % 3]) / dbl for i in range(3)], axis=1)
    sq = np.stack([np.einsum("ij,ij->i", e[i], e[i]) for i in range(3)], axis=1)
    if s != 1.0:  # cotangents are scale free; areas and squared lengths scale with s²
        dbl, sq = dbl * (s * s), sq * (s * s)
    return dbl, cot, sq


def stiffness_matrix(V, F):
    """Cotangent stiffness matrix ``L`` (positive semi-definite, rows sum to 0).

    Parameters
    ----------
    V : (n, 3) float64 ndarray
        Vertex positions.
    F : (m, 3) int ndarray
        Triangles (0-based indices into ``V``); every face must have a positive area.

    Returns
    -------
    L : (n, n) scipy.sparse.csc_matrix
        ``L[i, j] = -(cot a_ij + cot b_ij)/2`` off the diagonal, ``L[i, i] = -sum_j L[i, j]``.
        Dimensionless (invariant under scaling of ``V``).

    Examples
    --------
    >>> import numpy as np, open3d as o3d, o3dheat
    >>> V, F = o3dheat.as_arrays(o3d.t.geometry.TriangleMesh.create_sphere(1.0, 10))
    >>> L = o3dheat.stiffness_matrix(V, F)
    >>> bool(abs(L @ np.ones(len(V))).max() < 1e-12)
    True
    """
    F = np.asarray(F, dtype=np.int64)
    return _stiffness(len(V), F, _corner_geometry(V, F)[1])


def _stiffness(n, F, cot):
    # corner i weights the edge (i+1, i+2)
    I = np.concatenate([F[:, 1], F[:, 2], F[:, 0]])
    J = np.concatenate([F[:, 2], F[:, 0], F[:, 1]])
    w = -0.5 * np.concatenate([cot[:, 0], cot[:, 1], cot[:, 2]])
    diag = -np.bincount(I, weights=w, minlength=n) - np.bincount(J, weights=w, minlength=n)
    d = np.arange(n)
    return _assemble(n, np.concatenate([I, J, d]), np.concatenate([J, I, d]), np.concatenate([w, w, diag]))


def _assemble(n, I, J, w):
    """One sparse matrix from (row, col, value) triplets, duplicates summed: (n, n) CSC."""
    return sp.csc_matrix(sp.coo_matrix((w, (I, J)), shape=(n, n)))


def voronoi_areas(V, F):
    """Mixed Voronoi areas per vertex (Meyer, Desbrun, Schröder, Barr 2003).

    Non-obtuse triangles give each corner its Voronoi region; an obtuse triangle gives half its
    area to the obtuse corner and a quarter to each other one. The areas sum to the surface area.

    Parameters
    ----------
    V : (n, 3) float64 ndarray
    F : (m, 3) int ndarray

    Returns
    -------
    (n,) float64 ndarray
        In squared units of ``V``.

    Examples
    --------
    >>> import numpy as np, open3d as o3d, o3dheat
    >>> V, F = o3dheat.as_arrays(o3d.t.geometry.TriangleMesh.create_sphere(1.0, 10))
    >>> a = o3dheat.fem.voronoi_areas(V, F)
    >>> bool(np.isclose(a.sum(), o3dheat.mesh.face_areas(V, F).sum()))
    True
    """
    F = np.asarray(F, dtype=np.int64)
    return _voronoi(len(V), F, *_corner_geometry(V, F))


def _voronoi(n, F, dbl, cot, sq):
    area = 0.5 * dbl
    # Voronoi part at corner i: (|e_{i+1}|^2 cot_{i+1} + |e_{i+2}|^2 cot_{i+2}) / 8
    vor = np.stack([(sq[:, (i + 1) % 3] * cot[:, (i + 1) % 3] + sq[:, (i + 2) % 3] * cot[:, (i + 2) % 3]) / 8
                    for i in range(3)], axis=1)
    obtuse = cot < 0
    any_obtuse = obtuse.any(axis=1)
    vor[any_obtuse] = np.where(obtuse[any_obtuse], area[any_obtuse, None] / 2, area[any_obtuse, None] / 4)
    return np.bincount(F.reshape(-1), weights=vor.reshape(-1), minlength=n)


def operators(V, F, mass="consistent"):
    """The stiffness matrix, a mass matrix and the Voronoi areas in one pass over the faces.

    Parameters
    ----------
    V : (n, 3) float64 ndarray
    F : (m, 3) int ndarray
        Every face with a positive area.
    mass : str
        A key of :data:`MASS_KINDS`, as in :func:`mass_matrix`.

    Returns
    -------
    L, B : (n, n) scipy.sparse.csc_matrix
        Equal to :func:`stiffness_matrix` and :func:`mass_matrix` (the cotangents are computed once).
    areas : (n,) float64 ndarray
        Equal to :func:`voronoi_areas`.

    Examples
    --------
    >>> import numpy as np, open3d as o3d, o3dheat
    >>> V, F = o3dheat.as_arrays(o3d.t.geometry.TriangleMesh.create_box())
    >>> L, B, a = o3dheat.fem.operators(V, F)
    >>> round(float(B.sum()), 12), round(float(a.sum()), 12)
    (6.0, 6.0)
    """
    check_mass_kind(mass)
    V = np.asarray(V, dtype=np.float64)
    F = np.asarray(F, dtype=np.int64)
    n = len(V)
    geometry = _corner_geometry(V, F)
    L = _stiffness(n, F, geometry[1])
    areas = _voronoi(n, F, *geometry)
    B = sp.diags(areas).tocsc() if mass == "voronoi" else mass_matrix(V, F, mass)
    return L, B, areas


def mass_matrix(V, F, kind="consistent"):
    """Mass matrix ``B`` of the linear FEM.

    Parameters
    ----------
    V : (n, 3) float64 ndarray
    F : (m, 3) int ndarray
    kind : str
        A key of :data:`MASS_KINDS`: "consistent", ``B[i, j] = (|t_r| + |t_s|)/12``,
        ``B[i, i] = sum |t|/6`` (the paper's B); "lumped", its row sums on the diagonal;
        "voronoi", the mixed Voronoi areas on the diagonal; "identity", ``I``.

    Returns
    -------
    B : (n, n) scipy.sparse.csc_matrix
        Symmetric positive definite on referenced vertices; except for "identity", ``1ᵀ B 1`` is
        the surface area in squared units of ``V``.

    Examples
    --------
    >>> import numpy as np, open3d as o3d, o3dheat
    >>> V, F = o3dheat.as_arrays(o3d.t.geometry.TriangleMesh.create_box())
    >>> float(np.ones(len(V)) @ o3dheat.mass_matrix(V, F) @ np.ones(len(V)))
    6.0
    """
    check_mass_kind(kind)
    n = len(V)
    F = np.asarray(F, dtype=np.int64)
    if kind == "identity":
        return sp.identity(n, format="csc")
    if kind == "voronoi":
        return sp.diags(voronoi_areas(V, F)).tocsc()
    area = face_areas(np.asarray(V, dtype=np.float64), F)
    if kind == "lumped":
        return sp.diags(np.bincount(F.reshape(-1), weights=np.repeat(area / 3, 3), minlength=n)).tocsc()
    I = np.concatenate([F[:, 0], F[:, 1], F[:, 2]])
    J = np.concatenate([F[:, 1], F[:, 2], F[:, 0]])
    off = np.tile(area / 12, 3)
    diag = np.bincount(F.reshape(-1), weights=np.repeat(area / 6, 3), minlength=n)
    d = np.arange(n)
    return _assemble(n, np.concatenate([I, J, d]), np.concatenate([J, I, d]), np.concatenate([off, off, diag]))


def _vertex_normals(V, F):
    """Area-weighted vertex normals (unit length where defined)."""
    V = V / unit_scale(V)  # exact; unit normals do not depend on the scale
    n = np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]])  # 2 |t| times the face normal
    N = np.zeros_like(V)
    for i in range(3):
        np.add.at(N, F[:, i], n)
    length = np.linalg.norm(N, axis=1, keepdims=True)
    return np.divide(N, length, out=np.zeros_like(N), where=length > 0)


def mean_curvature(V, F):
    """Mean curvature per vertex from the FEM operators: ``H = ½ ⟨A⁻¹ L V, n⟩``.

    ``L V`` is the cotangent Laplacian of the coordinates (``−Δx = 2 H n`` on a smooth surface),
    ``A`` the mixed Voronoi areas and ``n`` the area-weighted vertex normal, so H > 0 where the
    surface bends away from its normal (a sphere with outward normals: ``H = 1/R``). Boundary
    vertices get the value of the same formula, which is not a curvature there.

    Parameters
    ----------
    V : (n, 3) float64 ndarray
    F : (m, 3) int ndarray

    Returns
    -------
    (n,) float64 ndarray
        In inverse units of ``V``; 0 at unreferenced vertices.

    Examples
    --------
    >>> import numpy as np, open3d as o3d, o3dheat
    >>> V, F = o3dheat.as_arrays(o3d.t.geometry.TriangleMesh.create_sphere(2.0, 40))
    >>> bool(abs(np.median(o3dheat.fem.mean_curvature(V, F)) - 0.5) < 0.01)
    True
    """
    V = np.asarray(V, dtype=np.float64)
    F = np.asarray(F, dtype=np.int64)
    L, _, a = operators(V, F, "identity")
    LV = L @ V
    H = 0.5 * np.einsum("ij,ij->i", LV, _vertex_normals(V, F))
    return np.divide(H, a, out=np.zeros(len(V)), where=a > 0)


def gaussian_curvature(V, F):
    """Gaussian curvature per vertex by the angle defect: ``K = (2π − Σ θ) / A`` (``π − Σ θ`` on
    the boundary), with the mixed Voronoi areas ``A``.

    Discrete Gauss–Bonnet holds exactly: ``Σ K A = 2π χ`` (with the boundary turning angles).

    Parameters
    ----------
    V : (n, 3) float64 ndarray
    F : (m, 3) int ndarray

    Returns
    -------
    (n,) float64 ndarray
        In inverse squared units of ``V``; 0 at unreferenced vertices.

    Examples
    --------
    >>> import numpy as np, open3d as o3d, o3dheat
    >>> V, F = o3dheat.as_arrays(o3d.t.geometry.TriangleMesh.create_sphere(1.0, 30))
    >>> K, A = o3dheat.fem.gaussian_curvature(V, F), o3dheat.fem.voronoi_areas(V, F)
    >>> round(float(K @ A / (2 * np.pi)), 9)      # χ of the sphere
    2.0
    """
    V = np.asarray(V, dtype=np.float64)
    F = np.asarray(F, dtype=np.int64)
    n = len(V)
    ang = np.zeros((len(F), 3))
    for i in range(3):
        u = V[F[:, (i + 1) % 3]] - V[F[:, i]]
        w = V[F[:, (i + 2) % 3]] - V[F[:, i]]
        ang[:, i] = np.arctan2(np.linalg.norm(np.cross(u, w), axis=1), np.einsum("ij,ij->i", u, w))
    total = np.bincount(F.reshape(-1), weights=ang.reshape(-1), minlength=n)
    E, counts = _edges(F)
    on_boundary = np.zeros(n, bool)
    on_boundary[E[counts == 1].reshape(-1)] = True
    defect = np.where(on_boundary, np.pi, 2 * np.pi) - total
    a = voronoi_areas(V, F)
    return np.divide(defect, a, out=np.zeros(n), where=a > 0)
