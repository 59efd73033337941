"""The generalized eigenproblem ``L x = λ B x`` of the linear FEM, and its result, :class:`Spectrum`.

The smallest ``k`` eigenpairs are found by shift-invert on one sparse Cholesky factor of
``L - σ B`` (``σ < 0``, so the matrix is positive definite even with several components), with
CHOLMOD -> cholespy -> SuperLU as factorization backends (:mod:`o3dheat.spectral.linalg`). Small problems,
or ``k`` close to ``n``, are solved densely.

Conventions: eigenvalues ascending and ``>= 0`` (``L`` is positive semi-definite); eigenvectors
B-orthonormal (``Xᵀ B X = I``); the sign of each eigenvector is fixed so that its entry of largest
magnitude is positive (first such entry on ties). Within a multiple eigenvalue (equal to the
solver's accuracy) the basis is a canonical one of the eigenspace, whatever basis the solver
found (:func:`_canonical_bases`): the same, to rounding, for every method, thread count and run;
bit for bit only where the eigenvalues are simple.
"""

from __future__ import annotations

import contextlib
import hashlib
import logging
import os
import sys
import time
from collections import OrderedDict
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from scipy.sparse.csgraph import reverse_cuthill_mckee

from o3dheat import checks, parallel
from o3dheat.errors import ConvergenceError, MeshError, SolverError
from o3dheat.geometry import prepare

from . import _cache, fem
from .lanczos import block_lanczos, rayleigh_ritz
from .linalg import factorize
from .memory import OutOfMemory, available_memory, check_memory

__all__ = ["Spectrum", "eigensolve", "eigensolve_operators", "peak_memory", "default_cache_dir", "shared_eigensolve", "set_cache",
           "memoized", "memoized_has", "cache_max_bytes", "inverse_mass_bound"]

log = logging.getLogger("o3dheat")

#: eigensolver methods of :func:`eigensolve` (``method=``): defined here only
METHODS = ("auto", "lanczos", "arpack", "dense")
DENSE_MAX_N = 1200
DENSE_LIMIT_N = 12_000  # above this a dense solve needs several GiB: never chosen automatically
# Measured (scripts/bench_spectrum.py, 2 cores): the block Lanczos wins from about 10k vertices,
# and from 3k when k >= 64 (1.1-2x at 3k-8k, k = 70-100); below, ARPACK's single-vector Lanczos on
# the same CHOLMOD factor needs fewer solves and less work (10-20% faster for k = 10-50).
LANCZOS_MIN_N = 10_000
LANCZOS_MANY_K = (64, 3_000)  # (k, n): from k eigenpairs on n vertices up, Lanczos as well
_CACHE_VERSION = "2"


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
        kernel signature (:meth:`o3dheat.HeatKernel.hks`). Exact for the diagonal masses;
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
    def n(self):
        """Number of vertices.

        Examples
        --------
        >>> import open3d as o3d, o3dheat
        >>> o3dheat.eigensolve(o3d.t.geometry.TriangleMesh.create_sphere(1.0, 8), k=5).n
        114
        """
        return self.eigenvectors.shape[0]

    @property
    def k(self):
        """Number of eigenpairs.

        Examples
        --------
        >>> import open3d as o3d, o3dheat
        >>> o3dheat.eigensolve(o3d.t.geometry.TriangleMesh.create_sphere(1.0, 8), k=5).k
        5
        """
        return len(self.eigenvalues)

    def save(self, path, overwrite=False):
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
        from o3dheat.io import atomic_write

        path = Path(path)
        if path.suffix.lower() != ".npz":
            raise MeshError(f"a spectrum is saved as .npz: {path}")
        if path.exists() and not overwrite:
            raise MeshError(f"{path} exists: pass overwrite=True to replace it")
        atomic_write(path, lambda fh: np.savez(fh, **_cache.spectrum_arrays(self)))

    @classmethod
    def load(cls, path):
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
            Not a readable spectrum file, or one that fails a check (named in the message).

        Examples
        --------
        See :meth:`save`.
        """
        fields = _cache.read_spectrum(path)
        s = cls(**fields, timings={"cache": True})
        _check_loaded(s, path)
        return s

    def __repr__(self):
        return (f"Spectrum(n={self.n}, k={self.k}, mass={self.mass_kind!r}, backend={self.backend!r}, "
                f"eigenvalues=[{self.eigenvalues[0]:.4g} .. {self.eigenvalues[-1]:.4g}])")


def _check_loaded(s, path):
    """The checks of :meth:`Spectrum.load` (a MeshError naming the first that fails)."""
    lam, X, L, B = s.eigenvalues, s.eigenvectors, s.stiffness, s.mass
    n, k = X.shape
    shapes = {"stiffness": L.shape, "mass": B.shape}
    for name, shape in shapes.items():
        if shape != (n, n):
            raise MeshError(f"{path}: {name} is {shape[0]} x {shape[1]}, the eigenvectors have {n} rows")
    for name, a in (("eigenvalues", lam), ("residuals", s.residuals), ("areas", s.areas)):
        if a.shape != ((k,) if name != "areas" else (n,)):
            raise MeshError(f"{path}: {name} has shape {a.shape}")
    bound = s.inverse_mass_bound
    if bound is not None and np.shape(bound) != (n,):
        raise MeshError(f"{path}: inverse_mass_bound has shape {np.shape(bound)}, not ({n},)")
    if not all(np.all(np.isfinite(a)) for a in (lam, X, L.data, B.data, s.residuals, s.areas)
               + (() if bound is None else (bound,))):
        raise MeshError(f"{path}: non-finite values")
    if np.any(s.areas < 0) or (bound is not None and np.any(bound < 0)):
        raise MeshError(f"{path}: negative areas or inverse-mass bound")
    if s.mass_kind != "given":
        try:
            fem.check_mass_kind(s.mass_kind)
        except MeshError as e:
            raise MeshError(f"{path}: {e}") from None
    if np.any(np.diff(lam) < 0) or lam[0] < 0:
        raise MeshError(f"{path}: the eigenvalues are not ascending and >= 0")
    if s.faces is not None and (s.faces.ndim != 2 or s.faces.shape[1] != 3 or s.faces.size
                                and (s.faces.min() < 0 or s.faces.max() >= n)):
        raise MeshError(f"{path}: faces of shape {s.faces.shape} do not index the {n} vertices")
    res = _residuals(L, B, lam, X)
    if res.max() > 1e-2 or np.any(res > np.maximum(10 * s.residuals, 1e-12)):
        raise MeshError(f"{path}: the eigenpairs do not solve L x = λ B x for the stored operators "
                        f"(residual {res.max():.1e}, stored {s.residuals.max():.1e})")
    G = X.T @ (B @ X)
    G[np.diag_indices(k)] -= 1.0
    if np.abs(G).max() > 1e-6:
        raise MeshError(f"{path}: the eigenvectors are not B-orthonormal (|XᵀBX - I| = {np.abs(G).max():.1e})")


def default_cache_dir():
    r"""Folder of the on-disk spectrum cache: ``$O3DHEAT_CACHE``, else the platform's user cache
    folder (``$XDG_CACHE_HOME/o3dheat`` or ``~/.cache/o3dheat`` on Linux, ``~/Library/Caches/o3dheat``
    on macOS, ``%LOCALAPPDATA%\o3dheat\Cache`` on Windows).

    Returns
    -------
    pathlib.Path

    Examples
    --------
    >>> import o3dheat.spectral.spectrum as s
    >>> "o3dheat" in str(s.default_cache_dir())
    True
    """
    env = os.environ.get("O3DHEAT_CACHE")
    if env:
        return Path(env)
    if sys.platform == "win32" and os.environ.get("LOCALAPPDATA"):
        return Path(os.environ["LOCALAPPDATA"]) / "o3dheat" / "Cache"
    if sys.platform == "darwin":
        return Path.home() / "Library" / "Caches" / "o3dheat"
    xdg = os.environ.get("XDG_CACHE_HOME")
    return (Path(xdg) if xdg and os.path.isabs(xdg) else Path.home() / ".cache") / "o3dheat"


def cache_max_bytes():
    """Size budget of the on-disk cache: ``$O3DHEAT_CACHE_MAX_MB`` megabytes, default 2048. The least
    recently used spectra are deleted beyond it.

    Returns
    -------
    int
        Bytes.

    Examples
    --------
    >>> import os, o3dheat.spectral.spectrum as s
    >>> "O3DHEAT_CACHE_MAX_MB" in os.environ or s.cache_max_bytes() == 2048 * 2**20
    True
    """
    return _megabytes("O3DHEAT_CACHE_MAX_MB", 2048)


def _megabytes(variable, default):
    """Bytes of the environment variable ``variable`` (megabytes), else of ``default``."""
    try:
        value = float(os.environ.get(variable, str(default)))
        if not value >= 0:  # negative or NaN: a budget of nothing is 0
            raise ValueError
        return int(value * 2**20)
    except (ValueError, OverflowError):  # not a number, negative, or inf
        raise MeshError(f"{variable} must be a number of megabytes >= 0, got {os.environ[variable]!r}") from None


# ------------------------------------------------------------------ the in-memory cache (shared)
_MEMORY: OrderedDict = OrderedDict()
_MEMORY_MAX = 8
_DISK = None


def memory_cache_max_bytes():
    """Size budget of the in-memory cache: ``$O3DHEAT_MEMORY_CACHE_MB`` megabytes, default 1024.
    Beyond it (or beyond 8 spectra) the least recently used spectra are dropped; the newest one is
    always kept, whatever its size (the filters of a chain share it).

    Returns
    -------
    int
        Bytes.

    Examples
    --------
    >>> import os, o3dheat.spectral.spectrum as s
    >>> "O3DHEAT_MEMORY_CACHE_MB" in os.environ or s.memory_cache_max_bytes() == 1024 * 2**20
    True
    """
    return _megabytes("O3DHEAT_MEMORY_CACHE_MB", 1024)


def _nbytes(value):
    """Bytes held by the arrays and sparse matrices among an object's attributes."""
    total = 0
    for v in (vars(value).values() if hasattr(value, "__dict__") else [value]):
        if isinstance(v, np.ndarray):
            total += v.nbytes
        elif sp.issparse(v):
            total += sum(getattr(v, a).nbytes for a in ("data", "indices", "indptr") if hasattr(v, a))
    return total


def set_cache(folder):
    """The disk folder used by :func:`shared_eigensolve` (and the filters): a folder, True
    (:func:`default_cache_dir`) or None (memory only, the default).

    Examples
    --------
    >>> import tempfile, o3dheat.spectral.spectrum as s
    >>> s.set_cache(tempfile.mkdtemp()); s.set_cache(None)
    """
    global _DISK
    _DISK = folder


def clear_cache():
    """Forget the spectra kept in memory (the disk cache stays).

    Examples
    --------
    >>> import o3dheat.spectral.spectrum as s
    >>> s.clear_cache()
    """
    _MEMORY.clear()


def memoized(key, compute):
    """``compute()``, remembered under ``key`` among the last results (least recently used first
    out: at most 8 and :func:`memory_cache_max_bytes`, the newest always kept): the one in-memory
    cache of spectra, for meshes and for operators built elsewhere.

    Parameters
    ----------
    key : hashable
        What identifies the result (e.g. a hash of the geometry and the settings).
    compute : callable
        Called without arguments when ``key`` is not remembered.

    Returns
    -------
    The result of ``compute()``, now or from an earlier call.

    Examples
    --------
    >>> import o3dheat.spectral.spectrum as s
    >>> calls = []
    >>> s.memoized(("example", 1), lambda: calls.append(1) or 42), s.memoized(("example", 1), lambda: 0)
    (42, 42)
    >>> len(calls)
    1
    """
    if key in _MEMORY:
        _MEMORY.move_to_end(key)
        return _MEMORY[key][0]
    value = compute()
    _MEMORY[key] = (value, _nbytes(value))
    budget = memory_cache_max_bytes()
    while len(_MEMORY) > 1 and (len(_MEMORY) > _MEMORY_MAX or sum(b for _, b in _MEMORY.values()) > budget):
        _MEMORY.popitem(last=False)
    return value


def memoized_has(key):
    """Whether :func:`memoized` holds a result for ``key`` now.

    Examples
    --------
    >>> import o3dheat.spectral.spectrum as s
    >>> s.memoized_has(("example", "absent"))
    False
    """
    return key in _MEMORY


def shared_eigensolve(V, F, k=100, mass="consistent", cache=None):
    """The spectrum of ``(V, F)``, computed once per geometry and settings and then shared (the
    last few in memory, see :func:`memoized`; on disk too with ``cache`` or :func:`set_cache`).

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
        Disk folder (True: :func:`default_cache_dir`); None: what :func:`set_cache` set.

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
    key = _cache_key(np.asarray(V), np.asarray(F), k, mass, "auto")  # the k asked for: a repeat is a hit

    def compute():  # capped at the vertices eigensolve solves on (prepare again there: O(n), once)
        r = len(prepare((V, F)).V)
        return eigensolve((V, F), k=min(k, r), mass=mass, cache=_DISK if cache is None else cache)

    return memoized(key, compute)


def _fix_signs(X, chunk=16):
    """In place: the entry of largest magnitude of each column becomes positive (the first one on
    ties). By column chunks shared out among threads: no n x k temporary."""

    def fix(a, z):
        Xc = X[:, a:z]
        s = np.sign(Xc[np.argmax(np.abs(Xc), axis=0), np.arange(Xc.shape[1])])
        s[s == 0] = 1.0
        Xc *= s

    parallel.run(fix, parallel.row_parts(X.shape[1], chunk))  # ranges of columns
    return X


def _residuals(L, B, lam, X, chunk=16, b_norms=False):
    """Normwise backward errors, computed in column chunks (no n x k temporaries), the chunks
    shared out among threads (each column is computed whole by one thread); with ``b_norms``, also
    the columns' B-norms squared ``xᵀ B x`` (from the same products)."""
    nL = abs(L).sum(axis=0).max()
    nB = abs(B).sum(axis=0).max()
    L, B = sp.csr_matrix(L), sp.csr_matrix(B)

    def backward_errors(a, z):
        Xc = np.ascontiguousarray(X[:, a:z])
        BXc = B @ Xc
        R = L @ Xc - BXc * lam[a:z]
        res = np.linalg.norm(R, axis=0) / ((nL + np.abs(lam[a:z]) * nB) * np.linalg.norm(Xc, axis=0) + 1e-300)
        return res, np.einsum("ij,ij->j", Xc, BXc)

    parts = parallel.run(backward_errors, parallel.row_parts(X.shape[1], chunk))
    res = np.concatenate([p[0] for p in parts])
    return (res, np.concatenate([p[1] for p in parts])) if b_norms else res


def _b_orthonormalize(X, B):
    """Make Xᵀ B X = I exactly (to rounding) with one Cholesky of the k x k Gram matrix."""
    G = X.T @ (B @ X)
    G = (G + G.T) / 2
    try:
        C = np.linalg.cholesky(G)
    except np.linalg.LinAlgError as e:
        raise SolverError("the eigenvectors are not linearly independent (eigensolver failure)") from e
    return sla.solve_triangular(C, X.T, lower=True).T


def _weyl_gap(B):
    """Weyl's law: λ_j ≈ 4π j / area, so 4π / area is the expected gap between eigenvalues."""
    return 4 * np.pi / float(B.sum())


def _shift(B):
    # a hundredth of the first gap below 0
    return -0.01 * _weyl_gap(B)


def all_zero(eigenvalues, mass):
    """Whether every eigenvalue is 0 to rounding (below 1e-8 of Weyl's gap ``4π / 1ᵀ B 1``): the
    spectrum then holds only the constants of the mesh's components."""
    return float(np.max(eigenvalues)) <= 1e-8 * _weyl_gap(mass)


def _cache_key(V, F, k, mass, method, tol=1e-8, sigma=None, seed=0, block=8):
    """Hash of everything that changes a spectrum: the geometry, k, the mass, and the solver
    settings (a tol=1e-2 answer must never be served to a tol=1e-10 call)."""
    h = hashlib.sha256()
    h.update(np.ascontiguousarray(V, dtype=np.float64).tobytes())
    h.update(np.ascontiguousarray(F, dtype=np.int64).tobytes())
    h.update(f"{V.shape}{F.shape}|{k}|{mass}|{method}|{float(tol)!r}|{sigma!r}|{seed}|{block}|"
             f"{_CACHE_VERSION}".encode())
    return h.hexdigest()[:32]


def _choose_method(method, r, k):
    """"dense", "arpack" or "lanczos" for r vertices and k eigenpairs (see eigensolve)."""
    many_k = k >= LANCZOS_MANY_K[0] and r >= LANCZOS_MANY_K[1]
    iterative = "lanczos" if r >= LANCZOS_MIN_N or many_k else "arpack"
    if method == "auto":
        method = "dense" if (r <= DENSE_MAX_N or k > r // 2) and r <= DENSE_LIMIT_N else iterative
    if k >= r - 1:
        method = "dense"  # ARPACK and the block Lanczos need k < n - 1
    if method == "dense" and r > DENSE_LIMIT_N:
        raise MeshError(f"a dense eigensolve of {r} vertices would need about "
                        f"{2 * 8 * r * r / 2**30:.0f} GiB: ask for k < {r - 1} eigenpairs with "
                        "method='auto' (iterative), or use a smaller mesh")
    return method


def _solve_arpack(L, B, k, sigma, backend, seed):
    # machine precision: a looser ARPACK tolerance was seen to miss copies of multiple eigenvalues
    t0 = time.perf_counter()
    fac = factorize(L - sigma * B, backend=backend)
    t1 = time.perf_counter()
    n = L.shape[0]
    op = spla.LinearOperator((n, n), matvec=fac.solve, dtype=np.float64)
    ncv = min(n - 1, max(2 * k + 1, 20))
    try:
        lam, X = spla.eigsh(L, k=k, M=B, sigma=sigma, which="LM", OPinv=op, ncv=ncv, tol=0.0,
                            v0=np.random.default_rng(seed).standard_normal(n), maxiter=max(1000, 20 * k))
    except spla.ArpackNoConvergence as e:
        raise ConvergenceError(f"the eigensolver did not converge for k={k}: {e}") from e
    return lam, X, fac.backend, t1 - t0, time.perf_counter() - t1


def _solve_lanczos(L, B, k, sigma, backend, seed, tol, block):
    # L, B come renumbered in CSR (_permuted): the format of fast products with blocks of vectors
    t0 = time.perf_counter()
    fac = factorize(L - sigma * B, backend=backend)
    t1 = time.perf_counter()
    used = fac.backend
    buf = {}  # block_lanczos keeps no solution past the next solve: one buffer per shape serves all

    # F821 silenced in solve: ruff sees the `del buf, fac` below, after solve's last call
    def solve(Y):
        if Y.shape not in buf:  # noqa: F821 - deleted after the last call
            buf[Y.shape] = np.empty(Y.shape)  # noqa: F821 - deleted after the last call
        return fac.solve(Y, out=buf[Y.shape])  # noqa: F821 - deleted after the last call

    _, Xv, info = block_lanczos(L, B, solve, k, sigma, block=block, tol=max(tol, 1e-14), seed=seed,
                                refine=False)
    del buf, solve
    del fac  # free the factorization before the Rayleigh-Ritz (peak memory)
    lam, X = rayleigh_ritz(L, B, Xv, overwrite=True)  # in the memory of the basis
    log.info("block Lanczos: %s", info)
    return lam, X, used, t1 - t0, time.perf_counter() - t1


def _permuted(A, perm):
    """``A[perm][:, perm]`` as CSR (the format of the products with blocks of vectors)."""
    return sp.csr_matrix(sp.csr_matrix(A)[perm][:, perm])


def _unpermuted(X, perm, chunk=32):
    """Rows of X back to the original numbering: ``out[perm] = X``, by column chunks (no n x k
    temporary beyond the result) shared out among threads."""
    out = np.empty(X.shape, order="F")
    parallel.run(lambda a, z: out.__setitem__((perm, slice(a, z)), X[:, a:z]),
                 parallel.row_parts(X.shape[1], chunk))  # ranges of columns
    return out


def _solve_dense(L, B, k):
    t0 = time.perf_counter()
    # up to DENSE_MAX_N the BLAS gains nothing from threads (measured), and when another process
    # keeps a core busy OpenBLAS' spinning threads made a 1152-vertex solve 90x slower: one thread
    small = L.shape[0] <= DENSE_MAX_N
    with parallel.blas_one_thread() if small else contextlib.nullcontext():
        lam, X = sla.eigh(L.toarray(), B.toarray(), subset_by_index=[0, k - 1])
    return lam, X, "dense", 0.0, time.perf_counter() - t0


def eigensolve(mesh, k=100, mass="consistent", sigma=None, backend="auto", cache=None,
               method="auto", tol=1e-8, seed=0, block=8):
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
        paper's "B := I" linear FEM kernel). The kernel variants (:data:`o3dheat.spectral.kernel.VARIANTS`)
        each name the mass of their eigenproblem.
    sigma : float, optional
        Shift, must be negative (``L - σ B`` is then positive definite). Default: a hundredth of
        the expected first gap (Weyl's law), below 0.
    backend : {"auto", "cholmod", "cholespy", "superlu"}
        Factorization backend (see :func:`o3dheat.spectral.linalg.factorize`).
    cache : None, True, str or Path
        On-disk cache folder (True: :func:`default_cache_dir`), keyed by a hash of ``V``, ``F``,
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
    if sigma is not None and not (np.isfinite(sigma) and sigma < 0):
        raise MeshError(f"sigma must be a negative number (L - sigma B must be positive definite), got {sigma}")
    cache_dir = None if cache in (None, False) else (default_cache_dir() if cache is True else Path(cache))
    key = _cache_key(prep.V, prep.F, k, mass, method, tol, sigma, seed, block) if cache_dir is not None else None
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
    cached = _cache_load(cache_dir, key) if key else None
    if cached is not None and not _cache_valid(cached, L.shape[0], k):
        log.warning("the cached spectrum %s does not solve this eigenproblem (tampered or corrupt): "
                    "recomputing", key)
        cached = None
    if cached is not None:
        lam, X, used, s, res = cached
        timings = {"assemble": t_asm, "factorize": 0.0, "solve": 0.0, "cache": True}
    else:
        try:
            lam, X, used, s, res, timings = _solve(L, B, k, method, sigma, backend, seed, tol, block)
        except MemoryError as e:  # past the estimate: still an error naming the problem, not a crash
            raise OutOfMemory(f"out of memory solving for {k} eigenpairs on {len(V)} vertices ({e}): ask for "
                              "fewer eigenpairs, or decimate the mesh") from e
        timings = {"assemble": t_asm, **timings}
        if key:
            _cache_save(cache_dir, key, lam, X, used, s, res)
    if u != 1.0:
        lam, X, s, B, areas = lam / (u * u), X / u, s / (u * u), B * (u * u), areas * (u * u)
    if all_zero(lam, B):  # only constants per component: say why
        from scipy.sparse.csgraph import connected_components

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


def inverse_mass_bound(B, mass):
    """An upper bound of ``diag(B⁻¹)`` for a mass of :data:`o3dheat.spectral.fem.MASS_KINDS` (or "given"):
    ``1 / B_ii`` for a diagonal mass (exact), ``4 / (B 1)_i`` for the consistent one (each
    element's mass ``|t|/12 (I + 1 1ᵀ)`` is at least a quarter of its lumped mass ``|t|/3 I``);
    None for a non-diagonal mass of unknown kind.

    Examples
    --------
    >>> import numpy as np, open3d as o3d, o3dheat
    >>> from o3dheat.spectral.spectrum import inverse_mass_bound
    >>> V, F = o3dheat.as_arrays(o3d.t.geometry.TriangleMesh.create_sphere(1.0, 8))
    >>> B = o3dheat.mass_matrix(V, F)
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


def peak_memory(n, k=100, block=8):
    """Estimated peak memory of an iterative :func:`eigensolve`, in bytes.

    The Lanczos basis (``max(2k, k + 4 block) + block`` vectors of ``n`` float64) plus 2 KiB per
    vertex for the Cholesky factor, the operators and the blocks of vectors, as measured on a mesh
    of 1M vertices (``scripts/bench_spectrum.py``: resident memory added while solving peaked at
    3.4 GiB for k = 100, 6.4 GiB for k = 300). A mesh fits when this is below the
    memory available; eigensolve refuses with :class:`o3dheat.spectral.memory.OutOfMemory` otherwise.

    Parameters
    ----------
    n : int
        Vertices.
    k, block : int
        As for :func:`eigensolve`.

    Returns
    -------
    int

    Examples
    --------
    >>> round(peak_memory(1_000_000, 100) / 2**30, 1), round(peak_memory(1_000_000, 300) / 2**30, 1)
    (3.5, 6.4)
    """
    basis = min(n, max(2 * k, k + 4 * block)) + block
    return int(n * (8 * basis + 2048))


def _solve(L, B, k, method, sigma, backend, seed, tol, block):
    """Smallest k eigenpairs of L x = λ B x: (λ, X B-orthonormal with fixed signs, backend, σ,
    residuals, timings).

    The chosen method falls back when it fails to converge (the block Lanczos on tiny meshes,
    whose Krylov space is nearly exhausted by a 2k-vector basis; ARPACK on hard clusters):
    "lanczos" -> "arpack" -> "dense", the last only where a dense solve fits in memory."""
    r = L.shape[0]
    method = _choose_method(method, r, k)
    chain = {"lanczos": ["lanczos", "arpack", "dense"], "arpack": ["arpack", "dense"]}.get(method, [method])
    chain = [m for m in chain if m != "dense" or r <= DENSE_LIMIT_N]
    if chain[0] == "dense":
        check_memory(3 * 8 * r * r, f"a dense eigensolve of {r} vertices", "ask for fewer eigenpairs (iterative)")
    else:
        check_memory(peak_memory(r, k, block),
                     f"the eigensolve of {k} eigenpairs on {r} vertices",
                     "ask for fewer eigenpairs, or decimate the mesh")
        free = available_memory()
        if free is not None and 3 * 8 * r * r > free:
            chain = [m for m in chain if m != "dense"]
    for i, m in enumerate(chain):
        try:
            return _solve_by(L, B, k, m, sigma, backend, seed, tol, block)
        except ConvergenceError as e:
            if i + 1 == len(chain):
                raise
            log.warning("eigensolver %r failed (%s): falling back to %r", m, e, chain[i + 1])


def _canonical_bases(lam, X, B, scale, rel=1e-9):
    """In place: the basis of each cluster of equal eigenvalues (to ``rel`` of ``scale``, the
    eigensolver's accuracy: numerically one eigenspace) made independent of how the solver chose
    it: ``X_c P`` with ``P`` the orthogonal polar factor of ``X_cᵀ B G``, ``G`` a fixed
    pseudo-random block. Any B-orthonormal basis ``X_c Q`` of the same space gives the same result
    (to rounding): ``polar(Qᵀ M) = Qᵀ polar(M)``. Four concurrent dense eigensolves (threads
    change the BLAS's rounding) rotated the sphere's multiple eigenvectors arbitrarily before."""
    lam = np.asarray(lam)
    tied = np.diff(lam) <= rel * np.maximum(np.abs(lam[1:]), scale)  # tied[i]: λ_i and λ_{i+1} one cluster
    if not tied.any():  # simple eigenvalues only: nothing to do (no copy, no conversion)
        return X
    B = sp.csr_matrix(B)
    starts = np.flatnonzero(np.r_[True, ~tied])
    for i, j in zip(starts, np.r_[starts[1:], len(lam)], strict=True):
        if j - i > 1:
            G = np.random.default_rng(20261201 + j - i).standard_normal((X.shape[0], j - i))
            U, _, Vt = np.linalg.svd(X[:, i:j].T @ (B @ G))
            X[:, i:j] = X[:, i:j] @ (U @ Vt)
    return X


def _solve_by(L, B, k, method, sigma, backend, seed, tol, block):
    B_in = B
    use_dense = method == "dense"
    s = float("nan") if use_dense else (_shift(B) if sigma is None else float(sigma))
    perm, t_perm = None, 0.0
    if use_dense:
        lam, X, used, t_fac, t_sol = _solve_dense(L, B, k)
    else:
        # renumber the vertices for memory locality (reverse Cuthill-McKee): the products with L and
        # B, which read rows of blocks of vectors at the neighbours' indices, are 2x faster on meshes
        # stored in a scattered order (decimated, remeshed); the results are numbered back
        t0 = time.perf_counter()
        perm = reverse_cuthill_mckee(sp.csr_matrix(L), symmetric_mode=True)
        L, B = _permuted(L, perm), _permuted(B, perm)
        t_perm = time.perf_counter() - t0
        if method == "arpack":
            lam, X, used, t_fac, t_sol = _solve_arpack(L, B, k, s, backend, seed)
        else:
            lam, X, used, t_fac, t_sol = _solve_lanczos(L, B, k, s, backend, seed, tol, block)
    t0 = time.perf_counter()
    order = np.argsort(lam, kind="stable")
    if np.any(order != np.arange(len(lam))):
        lam, X = lam[order], X[:, order]
    if not (np.all(np.isfinite(lam)) and np.all(np.isfinite(X))):
        raise SolverError("the eigensolver returned non-finite values")
    if method != "lanczos":  # its Rayleigh-Ritz already made X B-orthonormal
        X = _b_orthonormalize(X, B)
    lam = np.maximum(lam, 0.0)
    res = _residuals(L, B, lam, X)
    if perm is not None:
        X = _unpermuted(X, perm)
    X = _fix_signs(X)  # in the caller's numbering: "first entry on ties" is well defined there
    # after the signs: a multiple eigenvalue's canonical basis has its own signs (the polar factor
    # is unique), where "largest entry" ties to rounding on a symmetric mesh
    X = _canonical_bases(lam, X, B_in, _weyl_gap(B_in))
    t_sol += t_perm + time.perf_counter() - t0
    return lam, X, used, s, res, {"factorize": t_fac, "solve": t_sol, "cache": False}


def eigensolve_operators(L, B, k=100, sigma=None, backend="auto", method="auto", tol=1e-8, seed=0,
                         block=8):
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
    lam, X, used, s, res, timings = _solve(L, B, k, method, sigma, backend, seed, tol, block)
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


def _cache_load(folder, key):
    """``(eigenvalues, eigenvectors, backend, sigma, residuals)`` of a signed entry, else None."""
    z = _cache.cache_load(folder, key)
    if z is None:
        return None
    try:
        return (z["eigenvalues"], z["eigenvectors"], str(z["backend"]), float(z["sigma"]), z["residuals"])
    except (KeyError, ValueError, TypeError) as e:
        log.warning("ignoring the cache entry %s (%s)", key, e)
        return None


def _cache_valid(cached, r, k):
    """A signed entry (o3dheat's own write, :mod:`o3dheat.spectral._cache`) is used if it has the
    shapes of this problem, finite values and ascending eigenvalues (O(n k)): its residuals were
    checked when it was computed."""
    lam, X, _, _, res = cached
    if lam.shape != (k,) or X.shape != (r, k) or lam.dtype != np.float64 or X.dtype != np.float64:
        return False
    return bool(np.all(np.isfinite(lam)) and np.all(np.isfinite(X)) and np.all(np.diff(lam) >= 0)
                and lam[0] >= 0 and res.shape == (k,))


def _cache_save(folder, key, lam, X, backend, sigma, res):
    _cache.cache_save(folder, key, {"eigenvalues": lam, "eigenvectors": X, "backend": np.array(backend),
                                             "sigma": np.array(sigma), "residuals": res}, cache_max_bytes())
