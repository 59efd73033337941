"""The smallest eigenpairs of the linear FEM's ``L x = λ B x`` on a mesh: :func:`eigensolve`, :class:`Spectrum`.

Entry points: :func:`eigensolve` (a mesh), :func:`eigensolve_operators` (operators built
elsewhere), :func:`shared_eigensolve` (computed once per geometry and settings, then shared through
:mod:`o3dheat.spectral.cache`), :class:`Spectrum` (the result; :meth:`Spectrum.save`,
:meth:`Spectrum.load`), :func:`inverse_mass_bound`. The solvers themselves are in
:mod:`o3dheat.spectral._solvers`.

Notes
-----
The smallest ``k`` eigenpairs are found by shift-invert on one sparse Cholesky factor of
``L - σ B`` (``σ < 0``, so the matrix is positive definite even with several components), with
CHOLMOD -> cholespy -> SuperLU as factorization backends (:mod:`o3dheat.spectral.linalg`). Small
problems, or ``k`` close to ``n``, are solved densely.

Conventions: eigenvalues ascending and ``>= 0`` (``L`` is positive semi-definite); eigenvectors
B-orthonormal (``Xᵀ B X = I``); the sign of each eigenvector is fixed so that its entry of largest
magnitude is positive, magnitudes within 1e-6 (relative) of the largest counting as tied and the
first tied entry deciding (on a symmetric mesh the largest magnitudes are equal at mirrored
vertices, often with opposite signs: rounding must not choose). Within a multiple eigenvalue
(eigenvalues equal to 1e-9 relative) the basis is a canonical one of the eigenspace, with its own
signs, whatever basis the solver found (``_solvers._canonical_bases``). What is reproducible, and
to what accuracy: the Notes of :func:`eigensolve`.
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import scipy.sparse as sp
from numpy.typing import ArrayLike
from scipy.sparse.csgraph import connected_components

from o3dheat import checks
from o3dheat.errors import MeshError, OutOfMemory
from o3dheat.geometry import prepare
from o3dheat.io import atomic_write
from o3dheat.typing import MeshLike, PathLike

from . import _spectrum_files, fem
from ._solvers import solve_eigenproblem, weyl_gap
from .cache import SPECTRA, disk_folder, entry_valid, load_entry, memoized, save_entry, spectrum_key

__all__ = ["Spectrum", "eigensolve", "eigensolve_operators", "shared_eigensolve", "inverse_mass_bound"]

log = logging.getLogger("o3dheat")

#: eigensolver methods of :func:`eigensolve` (``method=``): defined here only
METHODS = ("auto", "lanczos", "arpack", "dense")


@dataclass
class Spectrum:
    """The smallest eigenpairs of ``L x = λ B x`` on a mesh, with the operators that define them.

    Attributes
    ----------
    eigenvalues : (k,) float64 ndarray
        Ascending, ``>= 0``, in units of 1/length² (for mass "identity": dimensionless).
    eigenvectors : (n, k) float64 ndarray
        B-orthonormal columns with fixed signs (0 at unreferenced vertices; the copies of a
        welded duplicate vertex share its value, see :mod:`o3dheat.geometry.welding`).
    stiffness : (n, n) scipy.sparse.csc_matrix
        The cotangent matrix ``L`` (on welded duplicates: ``P D⁻¹ L D⁻¹ Pᵀ``, see :mod:`o3dheat.geometry.welding`).
    mass : (n, n) scipy.sparse.csc_matrix
        ``B`` as chosen by ``mass_kind`` (the identity for "identity"; on welded duplicates
        ``P D⁻¹ B D⁻¹ Pᵀ``).
    mass_kind : str
        A key of :data:`o3dheat.spectral.fem.MASS_KINDS` (:func:`eigensolve_operators`: "given").
    areas : (n,) float64 ndarray
        Mixed Voronoi areas of the vertices (for the Voronoi kernel of eq. (7)); the copies of a
        welded vertex share its area equally (the row sums of the "voronoi" mass).
    backend : str
        Factorization used: "cholmod", "cholespy", "superlu", or "dense".
    residuals : (k,) float64 ndarray
        Normwise backward errors ``‖L x - λ B x‖ / ((‖L‖₁ + |λ| ‖B‖₁) ‖x‖)``.
    sigma : float
        The shift used (``nan`` for the dense solver).
    timings : dict
        Seconds spent per stage ("assemble", "factorize", "solve").
    faces : (m, 3) int64 ndarray or None
        The faces the operators were built on (after the repairs of :func:`o3dheat.geometry.welding.prepare`),
        in the caller's vertex numbering: what the topology of smoothed fields is computed on.
    inverse_mass_bound : (n,) float64 ndarray or None
        An upper bound of the diagonal of the inverse mass (of the welded vertex a vertex is a
        copy of; 0 at unreferenced vertices): the sum ``Σ_b x_b(i)²`` over a complete
        W-orthonormal eigenbasis, which bounds what a truncated spectrum leaves out of a heat
        kernel signature (:meth:`o3dheat.HeatKernel.hks <o3dheat.spectral.kernel.HeatKernel.hks>`). Exact for the diagonal masses;
        ``4 / (B 1)_i`` for the consistent mass (``B ⪰ D/4`` with ``D = diag(B 1)``: each
        element's mass is ``|t|/12 (I + 1 1ᵀ)``). None for a non-diagonal mass built elsewhere.

    Examples
    --------
    >>> import numpy as np, open3d as o3d, o3dheat
    >>> s = o3dheat.eigensolve(o3d.t.geometry.TriangleMesh.create_sphere(1.0, 8), k=5)
    >>> s.mass_kind, s.eigenvectors.shape
    ('consistent', (114, 5))
    >>> X, B = s.eigenvectors, s.mass
    >>> bool(np.allclose(X.T @ (B @ X), np.eye(5)))      # B-orthonormal
    True
    """

    eigenvalues: np.ndarray
    eigenvectors: np.ndarray
    stiffness: sp.csc_matrix
    mass: sp.csc_matrix
    mass_kind: str
    areas: np.ndarray
    backend: str
    residuals: np.ndarray
    sigma: float = float("nan")
    timings: dict = field(default_factory=dict)
    faces: np.ndarray | None = None
    inverse_mass_bound: np.ndarray | None = None

    @property
    def n(self) -> int:
        """Number of vertices.

        Examples
        --------
        >>> import open3d as o3d, o3dheat
        >>> o3dheat.eigensolve(o3d.t.geometry.TriangleMesh.create_sphere(1.0, 8), k=5).n
        114
        """
        return self.eigenvectors.shape[0]

    @property
    def k(self) -> int:
        """Number of eigenpairs.

        Examples
        --------
        >>> import open3d as o3d, o3dheat
        >>> o3dheat.eigensolve(o3d.t.geometry.TriangleMesh.create_sphere(1.0, 8), k=5).k
        5
        """
        return len(self.eigenvalues)

    def save(self, path: PathLike, overwrite: bool = False) -> None:
        """Write the spectrum to a self-contained ``.npz`` file: eigenpairs, operators, mass kind,
        areas, faces, residuals and the inverse-mass bound (everything :meth:`load` needs to give
        back an equal :class:`Spectrum`, without the mesh). Written atomically: an interrupted
        write leaves no file and an existing file is never half-overwritten.

        Parameters
        ----------
        path : str or Path
            Ends in ``.npz``.
        overwrite : bool
            Replace an existing file (default: refuse).

        Raises
        ------
        MeshError
            Not ``.npz``, the file exists and ``overwrite`` is False, or the folder does not exist.

        Examples
        --------
        >>> import os, tempfile, numpy as np, open3d as o3d, o3dheat
        >>> s = o3dheat.eigensolve(o3d.t.geometry.TriangleMesh.create_sphere(1.0, 8), k=5)
        >>> p = os.path.join(tempfile.mkdtemp(), "sphere.npz")
        >>> s.save(p)
        >>> t = o3dheat.Spectrum.load(p)
        >>> bool(np.array_equal(t.eigenvectors, s.eigenvectors)), t.mass_kind
        (True, 'consistent')
        """
        checks.flag(overwrite, "overwrite")
        path = Path(path)
        if path.is_dir():
            raise MeshError(f"{path} is a folder: give the spectrum's file name (e.g. {path / 'spectrum.npz'})")
        if path.suffix.lower() != ".npz":
            raise MeshError(f"a spectrum is saved as .npz: {path}")
        if path.exists() and not overwrite:
            raise MeshError(f"{path} exists: pass overwrite=True to replace it")
        atomic_write(path, lambda fh: np.savez(fh, **_spectrum_files.spectrum_arrays(self)))

    @classmethod
    def load(cls, path: PathLike) -> Spectrum:
        """Read a spectrum written by :meth:`save` (or ``o3dheat spectrum -o``), checked before it
        is returned: consistent shapes, finite values, ascending eigenvalues ``>= 0``, eigenpairs of
        the stored operators (residuals recomputed: at most ten times the stored ones, and 1e-2) and
        B-orthonormal eigenvectors (``‖Xᵀ B X − I‖_max <= 1e-6``). That they are the *smallest*
        eigenpairs is not checked (it needs a factorization): load only files you wrote.

        Parameters
        ----------
        path : str or Path
            A ``.npz`` file written by :meth:`save`.

        Returns
        -------
        Spectrum
            ``timings`` is ``{"cache": True}`` (nothing was computed).

        Raises
        ------
        MeshError
            Not a spectrum file, or one that fails a check (named in the message).
        NoSuchFile
            The file is missing (a MeshError and a FileNotFoundError).
        OSError
            The file cannot be read (a folder, no permission): the file system's own error.

        Examples
        --------
        See :meth:`save`.
        """
        fields = _spectrum_files.read_spectrum(path)
        s = cls(**fields, timings={"cache": True})
        _spectrum_files.check_loaded(s, path)
        return s

    def __repr__(self):
        return (f"Spectrum(n={self.n}, k={self.k}, mass={self.mass_kind!r}, backend={self.backend!r}, "
                f"eigenvalues=[{self.eigenvalues[0]:.4g} .. {self.eigenvalues[-1]:.4g}])")


def shared_eigensolve(V: ArrayLike, F: ArrayLike, k: int = 100, mass: str = "consistent",
                      cache: PathLike | bool | None = None) -> Spectrum:
    """The spectrum of ``(V, F)``, computed once per geometry and settings and then shared (the
    last few in memory, see :func:`o3dheat.spectral.cache.memoized`; on disk too with ``cache`` or :func:`o3dheat.spectral.cache.set_cache`).

    Parameters
    ----------
    V : (n, 3) float64 ndarray
        Vertex positions.
    F : (m, 3) int ndarray
        The triangles, as indices of their vertices.
    k : int
        Eigenpairs, capped at the number of vertices :func:`eigensolve` solves on (referenced,
        duplicates welded: an STL's triangle soup has three copies of each corner).
    mass : str
        A key of :data:`o3dheat.spectral.fem.MASS_KINDS`.
    cache : None, bool, str or Path
        Disk folder (True: :func:`o3dheat.spectral.cache.default_cache_dir`); None: what :func:`o3dheat.spectral.cache.set_cache` set.

    Returns
    -------
    Spectrum
        Shared: do not modify its arrays.

    Examples
    --------
    >>> import open3d as o3d, o3dheat.spectral.spectrum as s
    >>> m = o3d.t.geometry.TriangleMesh.create_sphere(1.0, 8)
    >>> V, F = m.vertex.positions.numpy(), m.triangle.indices.numpy()
    >>> s.shared_eigensolve(V, F, k=4) is s.shared_eigensolve(V, F, k=4)
    True
    """
    k = _check_k(k)
    key = spectrum_key(np.asarray(V), np.asarray(F), k, mass, "auto")  # the k asked for: a repeat is a hit

    def compute():  # capped at the vertices eigensolve solves on (prepare again there: O(n), once)
        r = len(prepare((V, F)).V)
        return eigensolve((V, F), k=min(k, r), mass=mass, cache=SPECTRA.disk if cache is None else cache)

    return memoized(key, compute)



def all_zero(eigenvalues: ArrayLike, mass: sp.spmatrix) -> bool:
    """Whether every eigenvalue is 0 to rounding (below 1e-8 of Weyl's gap ``4π / 1ᵀ B 1``): the
    spectrum then holds only the constants of the mesh's components."""
    return float(np.max(eigenvalues)) <= 1e-8 * weyl_gap(mass)




def eigensolve(mesh: MeshLike, k: int = 100, mass: str = "consistent", sigma: float | None = None,
               backend: str = "auto", cache: PathLike | bool | None = None, method: str = "auto",
               tol: float = 1e-8, seed: int = 0, block: int = 8) -> Spectrum:
    """Smallest ``k`` eigenpairs of the linear-FEM Laplace-Beltrami operator, ``L x = λ B x``.

    Parameters
    ----------
    mesh : o3d.t.geometry.TriangleMesh, o3d.geometry.TriangleMesh or (V, F) tuple
        Any triangle mesh; boundaries are free (Neumann). Repairs of :func:`o3dheat.geometry.welding.prepare`
        apply: exactly coincident vertices are welded (each copy gets its welded vertex's
        values), unreferenced vertices get 0 in every eigenvector.
    k : int
        Number of eigenpairs, ``1 <= k <= n`` (``n`` referenced vertices, after welding); ``k = n``
        is the full spectrum (dense solver).
    mass : str
        ``B``, a key of :data:`o3dheat.spectral.fem.MASS_KINDS`: the paper's consistent FEM mass, its
        lumped diagonal (row sums), the diagonal of mixed Voronoi areas (eq. (7)), or ``I`` (the
        paper's "B := I" linear FEM kernel). The kernel variants (:data:`o3dheat.spectral.variants.VARIANTS`)
        each name the mass of their eigenproblem.
    sigma : float, optional
        Shift, must be negative (``L - σ B`` is then positive definite). Default: a hundredth of
        the expected first gap (Weyl's law), below 0.
    backend : {"auto", "cholmod", "cholespy", "superlu"}
        Factorization backend (see :func:`o3dheat.spectral.linalg.factorize`).
    cache : None, True, str or Path
        On-disk cache folder (True: :func:`o3dheat.spectral.cache.default_cache_dir`), keyed by a hash of ``V``, ``F``,
        ``k``, ``mass`` and ``method``: a repeated call returns at once.
    method : str
        One of :data:`METHODS`. "lanczos": block shift-invert Lanczos
        (:func:`o3dheat.spectral.lanczos.block_lanczos`, the fast default); "arpack": SciPy's ``eigsh`` in
        shift-invert mode on the same factor; "dense": LAPACK on dense matrices. "auto" is dense for ``n <= 1200`` or ``k > n / 2``, "lanczos"
        from 10k vertices (and from 3k when ``k >= 64``), "arpack" otherwise (where each is
        measured faster).
    tol : float
        Relative residual asked of "lanczos", in (0, 1) (see :func:`o3dheat.spectral.lanczos.block_lanczos`): the
        default 1e-8 gives eigenvectors to about 1e-8 over the relative gap and eigenvalues equal
        to those of a machine-precision solve to better than 1e-10 relative. "arpack" always runs
        to machine precision (a looser ARPACK tolerance was seen to miss copies of multiple
        eigenvalues).
    seed : int
        Seed of the start vectors, ``>= 0`` (results are reproducible).
    block : int
        Block size of "lanczos" (right-hand sides per solve), from 1 to 256.

    Returns
    -------
    Spectrum

    Raises
    ------
    MeshError
        Bad mesh, ``k`` out of range, unknown ``mass``, positive ``sigma``.
    SolverError
        Factorization or eigensolver failure.

    Notes
    -----
    Reproducibility (eigenvectors compared column by column, in the module's sign and basis rules):

    - Called again, or from several threads at once, the serial result: each solve runs BLAS on one
      thread throughout, whatever other threads do (:func:`o3dheat.parallel.blas_one_thread`), and
      o3dheat's threads do not change sums: the same arithmetic (with OpenBLAS, the same bits). But
      "dense" above 1200 vertices runs LAPACK on the process's BLAS threads, one while another
      thread is in an o3dheat solve: it then agrees as below, eigenvalues to about 1e-12 relative.
    - Across methods, backends and machines: eigenvalues to the solver's accuracy (``tol``, or
      machine precision); a multiple eigenvalue's canonical basis to that accuracy (1e-10 at
      machine precision); other eigenvectors, signs included, to that accuracy over the relative
      gap to the nearest eigenvalue (a pair 1e-8 apart, relative: about 1e-6).
    - Not across methods: a multiple eigenvalue cut by ``k`` (λ_k equal to the uncomputed
      λ_{k+1}) has some basis of part of its eigenspace. Ask for a ``k`` that ends a cluster.

    Examples
    --------
    >>> import open3d as o3d, o3dheat
    >>> s = o3dheat.eigensolve(o3d.t.geometry.TriangleMesh.create_sphere(1.0, 20), k=4)
    >>> s.eigenvalues.round(1).tolist()
    [0.0, 2.0, 2.0, 2.0]
    """
    fem.check_mass_kind(mass)
    _check_method(method)
    k = _check_k(k)
    tol, seed, block = _check_settings(tol, seed, block)
    t0 = time.perf_counter()
    prep = prepare(mesh)
    V, F = prep.V, prep.F
    r = len(V)
    if k > r:
        raise MeshError(f"k={k} exceeds the number of (referenced) vertices {r}: ask for k <= {r}")
    if sigma is not None and (isinstance(sigma, bool) or not isinstance(sigma, (int, float, np.integer, np.floating))
                              or not (np.isfinite(sigma) and sigma < 0)):
        raise MeshError(f"sigma must be a negative number (L - sigma B must be positive definite), got {sigma}")
    cache_dir = disk_folder(cache)
    key = spectrum_key(prep.V, prep.F, k, mass, method, tol, sigma, seed, block) if cache_dir is not None else None
    # the area-weighted problems are solved at a power-of-two scale near 1 (exact: λ = λ'/u²,
    # X = X'/u, B = u² B'): iterative solvers lose digits when the units are far from the mesh's
    # size (micrometres, georeferenced metres); ordinary meshes (extent 1e-6..1e6) have u = 1
    extent = float(np.max(np.ptp(V, axis=0)))
    u = 1.0 if mass == "identity" or 2.0**-20 <= extent <= 2.0**20 else float(2.0 ** np.round(np.log2(extent)))
    try:
        L, B, areas = fem.operators(V / u if u != 1.0 else V, F, mass)
    except MemoryError as e:
        raise OutOfMemory(f"out of memory assembling the operators of {len(V)} vertices ({e}): decimate "
                          "the mesh") from e
    if sigma is not None:
        sigma = sigma * u * u
    t_asm = time.perf_counter() - t0
    cached = load_entry(cache_dir, key) if key else None
    if cached is not None and not entry_valid(cached, L.shape[0], k):
        log.warning("the cached spectrum %s does not solve this eigenproblem (tampered or corrupt): "
                    "recomputing", key)
        cached = None
    if cached is not None:
        lam, X, used, s, res = cached
        timings = {"assemble": t_asm, "factorize": 0.0, "solve": 0.0, "cache": True}
    else:
        try:
            lam, X, used, s, res, timings = solve_eigenproblem(L, B, k, method, sigma, backend, seed, tol, block)
        except MemoryError as e:  # past the estimate: still an error naming the problem, not a crash
            raise OutOfMemory(f"out of memory solving for {k} eigenpairs on {len(V)} vertices ({e}): ask for "
                              "fewer eigenpairs, or decimate the mesh") from e
        timings = {"assemble": t_asm, **timings}
        if key:
            save_entry(cache_dir, key, lam, X, used, s, res)
    if u != 1.0:
        lam, X, s, B, areas = lam / (u * u), X / u, s / (u * u), B * (u * u), areas * (u * u)
    if all_zero(lam, B):  # only constants per component: say why
        c = connected_components(L, directed=False)[0]
        log.warning("all %d eigenvalues are 0: the mesh has %d connected components, each with a constant "
                    "eigenfunction of eigenvalue 0; ask for k > %d to get non-constant ones", k, c, c)
    bound = inverse_mass_bound(B, mass)
    n = prep.n_input
    if r < n:  # unreferenced or welded vertices: operators P D⁻¹ A D⁻¹ Pᵀ, X_in = P X (see mesh)
        L, B = prep.expand_operator(L), prep.expand_operator(B)
        if prep.weld is not None:
            areas = areas / prep.multiplicity  # the copies share the area: its sum stays the area
        X, areas, bound = prep.expand(X), prep.expand(areas), prep.expand(bound)
    return Spectrum(lam, X, sp.csc_matrix(L), sp.csc_matrix(B), mass, areas, used, res, s, timings,
                    faces=prep.keep[F], inverse_mass_bound=bound)


def inverse_mass_bound(B: sp.spmatrix, mass: str) -> np.ndarray | None:
    """An upper bound of ``diag(B⁻¹)`` for a mass of :data:`o3dheat.spectral.fem.MASS_KINDS` (or "given"):
    ``1 / B_ii`` for a diagonal mass (exact), ``4 / (B 1)_i`` for the consistent one (each
    element's mass ``|t|/12 (I + 1 1ᵀ)`` is at least a quarter of its lumped mass ``|t|/3 I``);
    None for a non-diagonal mass of unknown kind.

    Examples
    --------
    >>> import numpy as np, open3d as o3d, o3dheat
    >>> from o3dheat.spectral.spectrum import inverse_mass_bound
    >>> V, F = o3dheat.as_arrays(o3d.t.geometry.TriangleMesh.create_sphere(1.0, 8))
    >>> B = o3dheat.mass_matrix((V, F))
    >>> bool(np.all(np.linalg.inv(B.toarray()).diagonal() <= inverse_mass_bound(B, "consistent")))
    True
    """
    B = sp.csr_matrix(B)
    d = B.diagonal()
    if mass != "consistent" and sp.csr_matrix(B - sp.diags(d)).count_nonzero() == 0:
        with np.errstate(divide="ignore"):
            return np.where(d > 0, 1.0 / np.where(d > 0, d, 1.0), np.inf)  # a zero mass: no bound
    if mass == "consistent":
        return 4.0 / np.asarray(B.sum(axis=1)).ravel()
    return None



def eigensolve_operators(L: sp.spmatrix, B: sp.spmatrix, k: int = 100, sigma: float | None = None,
                         backend: str = "auto", method: str = "auto", tol: float = 1e-8, seed: int = 0,
                         block: int = 8) -> Spectrum:
    """The smallest k eigenpairs of ``L x = λ B x`` for operators built elsewhere.

    For Laplacians that do not come from a triangle mesh, for example robust-laplacian's
    point-cloud Laplacian. The result has no faces (no topology) and ``mass_kind="given"``.

    Parameters
    ----------
    L : (n, n) sparse matrix
        Symmetric positive semi-definite.
    B : (n, n) sparse matrix
        Symmetric positive definite.
    k, sigma, backend, method, tol, seed, block
        As for :func:`eigensolve`.

    Returns
    -------
    Spectrum

    Examples
    --------
    >>> import numpy as np, scipy.sparse as sp
    >>> from o3dheat.spectral.spectrum import eigensolve_operators
    >>> L = sp.diags([np.r_[1, 2 * np.ones(8), 1], -np.ones(9), -np.ones(9)], [0, 1, -1])  # a path graph
    >>> eigensolve_operators(L, sp.identity(10), k=2).eigenvalues.round(4).tolist()
    [0.0, 0.0979]
    """
    _check_method(method)
    L, B = sp.csc_matrix(L, dtype=np.float64), sp.csc_matrix(B, dtype=np.float64)
    n = L.shape[0]
    if L.shape != (n, n) or B.shape != (n, n):
        raise MeshError(f"L and B must be square and of one size, got {L.shape} and {B.shape}")
    if abs(L - L.T).max() > 1e-10 * abs(L).max() or abs(B - B.T).max() > 1e-10 * abs(B).max():
        raise MeshError("L and B must be symmetric")
    k = _check_k(k)
    tol, seed, block = _check_settings(tol, seed, block)
    if k > n:
        raise MeshError(f"k={k} exceeds the size {n}")
    lam, X, used, s, res, timings = solve_eigenproblem(L, B, k, method, sigma, backend, seed, tol, block)
    areas = np.asarray(B.sum(axis=1)).ravel()
    return Spectrum(lam, X, L, B, "given", areas, used, res, s, timings,
                    inverse_mass_bound=inverse_mass_bound(B, "given"))


def _check_method(method):
    if not isinstance(method, str) or method not in METHODS:
        raise MeshError(f"unknown method {method!r}: use one of {', '.join(METHODS)}")


def _check_settings(tol, seed, block):
    """The solver settings, checked: tol in (0, 1), seed an integer >= 0, block from 1 to 256."""
    seed = checks.count(seed, "seed", minimum=0, maximum=2**63 - 1)
    return checks.tolerance(tol), seed, checks.count(block, "block", 1, 256)


def _check_k(k):
    if isinstance(k, bool) or not isinstance(k, (int, np.integer)):
        raise MeshError(f"k must be a positive integer, got {k!r}")
    if k <= 0:
        raise MeshError(f"k must be at least 1, got {k}")
    return int(k)
