"""Linear-FEM operators on triangle meshes: :func:`stiffness_matrix`, :func:`mass_matrix`, :func:`operators`.

Entry points: :func:`stiffness_matrix` (cotangent), :func:`mass_matrix` (consistent, lumped,
Voronoi, identity: :data:`MASS_KINDS`), :func:`voronoi_areas` (mixed), :func:`operators` (all of
them at once), :func:`adjacency_pattern`, :func:`mean_curvature`, :func:`gaussian_curvature`,
:func:`check_mass_kind`.

Notes
-----
Conventions (the paper's eq. (3), sign flipped so that L is positive semi-definite):

* ``L[i, j] = -(cot a_ij + cot b_ij) / 2`` for an edge ``ij`` (one cotangent on a boundary edge),
  ``L[i, i] = -sum_j L[i, j]``: symmetric, rows sum to 0, eigenvalues >= 0. ``L`` does not change
  when the mesh is scaled.
* ``B[i, j] = (|t_r| + |t_s|) / 12`` for an edge shared by triangles ``t_r, t_s``,
  ``B[i, i] = sum_{t ∋ i} |t| / 6``: the Gram matrix of the hat functions, symmetric positive
  definite, ``1ᵀ B 1`` = surface area; it scales with the square of the mesh size.
* lumped mass: ``diag(B 1)`` (a third of the area of the triangles at a vertex);
  Voronoi mass: ``diag(a)`` with the mixed Voronoi areas ``a`` of Meyer et al. (2003).

The public operators :func:`stiffness_matrix` and :func:`mass_matrix` (``o3dheat.stiffness_matrix``,
``o3dheat.mass_matrix``) take a mesh, like every o3dheat function: an Open3D mesh (tensor or legacy),
a ``(V, F)`` pair or a mesh-like (checked by :func:`o3dheat.as_arrays <o3dheat.geometry.mesh.as_arrays>`);
their former call with two arrays, ``mass_matrix(V, F)``, still works and warns (DeprecationWarning).
The module's other functions take ``V (n, 3) float64`` and ``F (m, 3) int`` arrays. The operators
are ``scipy.sparse.csc_matrix`` of shape ``(n, n)``, float64; the areas and curvatures ``(n,)`` float64.

The mass kinds (:data:`MASS_KINDS`) name matrices. A user names an eigenproblem by its kernel
variant (:data:`o3dheat.spectral.variants.VARIANTS`: "weighted" is the consistent mass, "linear"
the identity, "voronoi" and "lumped" their own): ``o3dheat spectrum --mass`` takes the variant names.
"""

from __future__ import annotations

import functools
import warnings

import numpy as np
import scipy.sparse as sp
from numpy.typing import ArrayLike

from o3dheat.errors import MeshError, OutOfMemory
from o3dheat.geometry import _loops as loops
from o3dheat.geometry._tables import edges, unit_scale, vertex_normals
from o3dheat.geometry.mesh import as_arrays
from o3dheat.typing import MeshLike

__all__ = ["stiffness_matrix", "mass_matrix", "voronoi_areas", "operators", "adjacency_pattern", "mean_curvature",
           "gaussian_curvature", "MASS_KINDS", "check_mass_kind"]

#: mass kind -> what the matrix is: the one definition of the masses of ``L x = λ B x``, used by
#: :func:`o3dheat.eigensolve <o3dheat.spectral.spectrum.eigensolve>`, :func:`o3dheat.diffuse <o3dheat.spectral.diffusion.diffuse>` and the kernel variants
#: (:data:`o3dheat.spectral.variants.VARIANTS` names a mass of this table; ``o3dheat spectrum --mass``
#: takes the variant names, and the keys here that differ from them as deprecated spellings)
MASS_KINDS = {
    "consistent": "the paper's consistent FEM mass B, B_rs = (|t_r| + |t_s|)/12, B_ii = Σ|t|/6",
    "lumped": "diag(B 1), the row sums of B: a third of the area of the triangles at each vertex",
    "voronoi": "diag(a), the mixed Voronoi areas a of Meyer et al. (2003)",
    "identity": "I, the paper's 'B := I' (eigenpairs of L x = λ x)",
}


def check_mass_kind(kind: str) -> str:
    """``kind`` if it is a key of :data:`MASS_KINDS`, else a :class:`~o3dheat.errors.MeshError` listing them.

    Examples
    --------
    >>> from o3dheat.spectral.fem import check_mass_kind
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
    """Per-face double areas and the cotangent at each corner (m, 3), and the squared lengths of
    the edges opposite the corners (m, 3)."""
    V = np.asarray(V, dtype=np.float64)
    F = np.asarray(F, dtype=np.int64)
    s = unit_scale(V)  # computed at unit scale (exact power of two), scaled back below
    dbl, cot, sq = loops.corner_geometry(V / s if s != 1.0 else V, F)
    if np.any(dbl <= 0):
        raise MeshError(f"{int(np.sum(dbl <= 0))} faces have zero area: repair the mesh first "
                        "(o3dheat.geometry.welding.prepare drops them)")
    if s != 1.0:  # cotangents are scale free; areas and squared lengths scale with s²
        dbl, sq = dbl * (s * s), sq * (s * s)
    return dbl, cot, sq


def adjacency_pattern(F: ArrayLike, n: int) -> tuple[np.ndarray, np.ndarray]:
    """The sparsity pattern of the stiffness (and of the consistent mass): the vertex adjacency of
    the faces, diagonal included, as CSC ``(indptr, indices)`` (sorted; int32 below 2^31 entries).
    Known before any value, for example to analyse a factorization meanwhile
    (:func:`o3dheat.spectral.linalg.analyze`).

    Parameters
    ----------
    F : (m, 3) int ndarray
        The triangles, as indices of their vertices (< n).
    n : int
        Vertices.

    Returns
    -------
    indptr : (n + 1,) int ndarray
    indices : (nnz,) int ndarray

    Examples
    --------
    >>> import numpy as np
    >>> from o3dheat.spectral.fem import adjacency_pattern
    >>> indptr, indices = adjacency_pattern(np.array([[0, 1, 2]]), 3)
    >>> indptr.tolist(), indices.tolist()
    ([0, 3, 6, 9], [0, 1, 2, 0, 1, 2, 0, 1, 2])
    """
    indptr, indices = loops.pattern(np.asarray(F, dtype=np.int64), int(n))
    if len(indices) < 2**31:  # scipy's own index type for such sizes (its products are faster on it)
        indptr, indices = indptr.astype(np.int32), indices.astype(np.int32)
    return indptr, indices


def _assembled(V, F, consistent, pattern=None):
    """(L, B or None, Voronoi areas, lumped mass) in one pass over the faces, L and B on one
    sparsity pattern (CSC: symmetric, so the CSR arrays are the CSC ones)."""
    F = np.asarray(F, dtype=np.int64)
    n = len(V)
    dbl, cot, sq = _corner_geometry(V, F)
    indptr, indices = adjacency_pattern(F, n) if pattern is None else pattern
    Ld, Bd, vor, lumped = loops.fill(F, cot, dbl, sq, indptr, indices, n, consistent)
    L = sp.csc_matrix((Ld, indices, indptr), shape=(n, n))
    B = sp.csc_matrix((Bd, indices.copy(), indptr.copy()), shape=(n, n)) if consistent else None
    return L, B, vor, lumped


def _mesh_first(operator):
    """``operator(mesh, ...)``, also called the former way, ``operator(V, F, ...)`` (two arrays), with a
    DeprecationWarning. The arrays of the former call are used as they are (its checks and messages
    unchanged); a mesh is checked by :func:`~o3dheat.geometry.mesh.as_arrays`."""

    @functools.wraps(operator)
    def call(mesh, *args, **kwargs):
        if args and not isinstance(args[0], str) and hasattr(args[0], "__len__"):  # (V, F, ...): the former call
            name = operator.__name__
            warnings.warn(f"o3dheat.{name}(V, F, ...) is deprecated: pass one mesh, like every o3dheat function: "
                          f"o3dheat.{name}((V, F), ...) or an Open3D mesh", DeprecationWarning, stacklevel=2)
            return operator(_Arrays(mesh, args[0]), *args[1:], **kwargs)
        return operator(mesh, *args, **kwargs)

    return call


class _Arrays(tuple):
    """The ``(V, F)`` of the former two-array call, taken as they are (not through ``as_arrays``)."""

    __slots__ = ()

    def __new__(cls, V, F):
        return super().__new__(cls, (V, F))


def _vertices_and_faces(mesh):
    if isinstance(mesh, _Arrays):
        return np.asarray(mesh[0], dtype=np.float64), mesh[1]
    return as_arrays(mesh)


@_mesh_first
def stiffness_matrix(mesh: MeshLike) -> sp.csc_matrix:
    """Cotangent stiffness matrix ``L`` (positive semi-definite, rows sum to 0).

    Parameters
    ----------
    mesh : o3d.t.geometry.TriangleMesh, o3d.geometry.TriangleMesh, (V, F) tuple or mesh-like
        The surface (:func:`o3dheat.as_arrays <o3dheat.geometry.mesh.as_arrays>`): ``V`` ``(n, 3)``
        vertex positions, ``F`` ``(m, 3)`` 0-based triangles, every face with a positive area.
        ``stiffness_matrix(V, F)`` (two arrays, the former call) still works and warns
        (DeprecationWarning).

    Returns
    -------
    L : (n, n) scipy.sparse.csc_matrix
        ``L[i, j] = -(cot a_ij + cot b_ij)/2`` off the diagonal, ``L[i, i] = -sum_j L[i, j]``.
        Dimensionless (invariant under scaling of ``V``).

    Examples
    --------
    >>> import numpy as np, open3d as o3d, o3dheat
    >>> mesh = o3d.t.geometry.TriangleMesh.create_sphere(1.0, 10)
    >>> L = o3dheat.stiffness_matrix(mesh)
    >>> bool(abs(L @ np.ones(L.shape[0])).max() < 1e-12)
    True
    >>> V, F = o3dheat.as_arrays(mesh)
    >>> (o3dheat.stiffness_matrix((V, F)) != L).nnz       # arrays: one (V, F) pair
    0
    """
    V, F = _vertices_and_faces(mesh)
    return _assembled(V, F, consistent=False)[0]


def voronoi_areas(V: ArrayLike, F: ArrayLike) -> np.ndarray:
    """Mixed Voronoi areas per vertex (Meyer, Desbrun, Schröder, Barr 2003).

    Non-obtuse triangles give each corner its Voronoi region; an obtuse triangle gives half its
    area to the obtuse corner and a quarter to each other one. The areas sum to the surface area.

    Parameters
    ----------
    V : (n, 3) float64 ndarray
        Vertex positions.
    F : (m, 3) int ndarray
        The triangles, as indices of their vertices.

    Returns
    -------
    (n,) float64 ndarray
        In squared units of ``V``.

    Examples
    --------
    >>> import numpy as np, open3d as o3d, o3dheat
    >>> V, F = o3dheat.as_arrays(o3d.t.geometry.TriangleMesh.create_sphere(1.0, 10))
    >>> a = o3dheat.spectral.fem.voronoi_areas(V, F)
    >>> bool(np.isclose(a.sum(), o3dheat.geometry.mesh.face_areas(V, F).sum()))
    True
    """
    return _assembled(V, F, consistent=False)[2]


def operators(V: ArrayLike, F: ArrayLike, mass: str = "consistent", pattern: tuple | None = None) -> tuple[sp.csc_matrix, sp.csc_matrix, np.ndarray]:
    """The stiffness matrix, a mass matrix and the Voronoi areas in one pass over the faces.

    Parameters
    ----------
    V : (n, 3) float64 ndarray
        Vertex positions.
    F : (m, 3) int ndarray
        Every face with a positive area.
    mass : str
        A key of :data:`MASS_KINDS`, as in :func:`mass_matrix`.
    pattern : (indptr, indices), optional
        :func:`adjacency_pattern` of ``F``, when already computed (``L`` then shares its arrays).

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
    >>> L, B, a = o3dheat.spectral.fem.operators(V, F)
    >>> round(float(B.sum()), 12), round(float(a.sum()), 12)
    (6.0, 6.0)
    """
    check_mass_kind(mass)
    try:
        L, B, areas, lumped = _assembled(np.asarray(V, dtype=np.float64), F, mass == "consistent", pattern)
        return L, _mass(mass, B, areas, lumped), areas
    except MemoryError as e:  # numba's and numpy's: the error of every o3dheat stage that runs out of memory
        raise OutOfMemory(f"out of memory assembling the operators of {len(V):,} vertices ({e}): decimate the "
                          "mesh or allow more memory") from e


def _mass(kind, B, areas, lumped):
    if kind == "consistent":
        return B
    if kind == "identity":
        return sp.identity(len(areas), format="csc")
    return sp.diags(areas if kind == "voronoi" else lumped).tocsc()


@_mesh_first
def mass_matrix(mesh: MeshLike, kind: str = "consistent") -> sp.csc_matrix:
    """Mass matrix ``B`` of the linear FEM.

    Parameters
    ----------
    mesh : o3d.t.geometry.TriangleMesh, o3d.geometry.TriangleMesh, (V, F) tuple or mesh-like
        The surface (:func:`o3dheat.as_arrays <o3dheat.geometry.mesh.as_arrays>`): ``V`` ``(n, 3)``
        vertex positions, ``F`` ``(m, 3)`` 0-based triangles. ``mass_matrix(V, F)`` and
        ``mass_matrix(V, F, kind)`` (two arrays, the former call) still work and warn
        (DeprecationWarning).
    kind : str
        A key of :data:`MASS_KINDS`: "consistent", ``B[i, j] = (|t_r| + |t_s|)/12``,
        ``B[i, i] = sum |t|/6`` (the paper's B); "lumped", its row sums on the diagonal;
        "voronoi", the mixed Voronoi areas on the diagonal; "identity", ``I``. These name the
        matrix; the kernel variant of each (:data:`o3dheat.spectral.variants.VARIANTS`, the names of
        ``o3dheat spectrum --mass``) is :func:`o3dheat.spectral.variants.variant_of_mass`.

    Returns
    -------
    B : (n, n) scipy.sparse.csc_matrix
        Symmetric positive definite on referenced vertices; except for "identity", ``1ᵀ B 1`` is
        the surface area in squared units of ``V``.

    Examples
    --------
    >>> import numpy as np, open3d as o3d, o3dheat
    >>> box = o3d.t.geometry.TriangleMesh.create_box()
    >>> B = o3dheat.mass_matrix(box)
    >>> float(np.ones(B.shape[0]) @ B @ np.ones(B.shape[0]))      # the area
    6.0
    >>> V, F = o3dheat.as_arrays(box)
    >>> float(o3dheat.mass_matrix((V, F), "lumped").diagonal().sum())   # arrays: one (V, F) pair
    6.0
    """
    check_mass_kind(kind)
    V, F = _vertices_and_faces(mesh)
    if kind == "identity":
        return sp.identity(len(V), format="csc")
    _, B, areas, lumped = _assembled(V, F, consistent=kind == "consistent")
    return _mass(kind, B, areas, lumped)


def mean_curvature(V: ArrayLike, F: ArrayLike) -> np.ndarray:
    """Mean curvature per vertex from the FEM operators: ``H = ½ ⟨A⁻¹ L V, n⟩``.

    ``L V`` is the cotangent Laplacian of the coordinates (``−Δx = 2 H n`` on a smooth surface),
    ``A`` the mixed Voronoi areas and ``n`` the area-weighted vertex normal, so H > 0 where the
    surface bends away from its normal (a sphere with outward normals: ``H = 1/R``). Boundary
    vertices get the value of the same formula, which is not a curvature there.

    Parameters
    ----------
    V : (n, 3) float64 ndarray
        Vertex positions.
    F : (m, 3) int ndarray
        The triangles, as indices of their vertices.

    Returns
    -------
    (n,) float64 ndarray
        In inverse units of ``V``; 0 at unreferenced vertices.

    Examples
    --------
    >>> import numpy as np, open3d as o3d, o3dheat
    >>> V, F = o3dheat.as_arrays(o3d.t.geometry.TriangleMesh.create_sphere(2.0, 40))
    >>> bool(abs(np.median(o3dheat.spectral.fem.mean_curvature(V, F)) - 0.5) < 0.01)
    True
    """
    V = np.asarray(V, dtype=np.float64)
    F = np.asarray(F, dtype=np.int64)
    L, _, a = operators(V, F, "identity")
    LV = L @ V
    H = 0.5 * np.einsum("ij,ij->i", LV, vertex_normals(V, F))
    return np.divide(H, a, out=np.zeros(len(V)), where=a > 0)


def gaussian_curvature(V: ArrayLike, F: ArrayLike) -> np.ndarray:
    """Gaussian curvature per vertex by the angle defect: ``K = (2π − Σ θ) / A`` (``π − Σ θ`` on
    the boundary), with the mixed Voronoi areas ``A``.

    Discrete Gauss–Bonnet holds exactly: ``Σ K A = 2π χ`` (with the boundary turning angles).

    Parameters
    ----------
    V : (n, 3) float64 ndarray
        Vertex positions.
    F : (m, 3) int ndarray
        The triangles, as indices of their vertices.

    Returns
    -------
    (n,) float64 ndarray
        In inverse squared units of ``V``; 0 at unreferenced vertices.

    Examples
    --------
    >>> import numpy as np, open3d as o3d, o3dheat
    >>> V, F = o3dheat.as_arrays(o3d.t.geometry.TriangleMesh.create_sphere(1.0, 30))
    >>> K, A = o3dheat.spectral.fem.gaussian_curvature(V, F), o3dheat.spectral.fem.voronoi_areas(V, F)
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
    E, counts = edges(F)
    on_boundary = np.zeros(n, bool)
    on_boundary[E[counts == 1].reshape(-1)] = True
    defect = np.where(on_boundary, np.pi, 2 * np.pi) - total
    a = voronoi_areas(V, F)
    return np.divide(defect, a, out=np.zeros(n), where=a > 0)
