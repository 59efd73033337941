"""The full heat kernel without eigenpairs: ``Φ_t f = exp(−(t/2) W⁻¹L) f`` to a stated tolerance
at any time, for every kernel variant; entry points :func:`heat_flow` and :class:`HeatFlow`.

Why: the spectral kernel ``X_k D_t X_kᵀ W f`` of :class:`o3dheat.HeatKernel` is band-limited to
the ``k`` smallest eigenpairs. At the paper's scales ``t_i = (i/10)/λ_k`` the dropped eigenpairs
would keep ``exp(−λ_k t_1 / 2) = 95%`` of their weight in the full kernel, so there the truncation,
not ``t``, does the smoothing (``k`` acts as a second smoothing parameter, as in the paper's
Fig. 7). The full kernel ``K_t = exp(−(t/2) W⁻¹L)`` is the one of eq. (5)-(6) without truncation;
``W`` is the variant's mass (:data:`o3dheat.spectral.kernel.VARIANTS`).

How: shift-and-invert Lanczos (:mod:`o3dheat.spectral.krylov`) on a sparse Cholesky factor of
``W + γL`` (:func:`o3dheat.spectral.linalg.factorize`): one factor for times within a ratio of
:data:`SPLIT_RANGE`, two or more beyond (:func:`shift_groups`; ``γ`` from :func:`shift`), the
factors sharing one symbolic analysis (made on another core while the operators are assembled)
and the next one made on another core during the current one's solves. Factors are kept with the
mesh's operators for later calls on the same geometry (the in-memory cache of
:func:`o3dheat.spectral.cache.memoized`). The cost: assembling the operators and one factorization,
plus about 27 solves for the paper's ten scales, or about 70 over two factors for times spanning
four decades (to 1e-8; independent of the mesh size, measured by ``scripts/bench_heat.py``).

Why "spectral" stays the default of the filters, the studies and the figures
(:data:`METHODS`): it is the paper's computation, in which ``k`` is a second smoothing parameter;
one spectrum serves every field, the heat kernel signatures and the canonic basis of a mesh; and
its results now carry a certificate of their distance to the full kernel
(:meth:`o3dheat.HeatKernel.truncation_bound`). The exact form is one keyword away
(``method="exact"``) and is the right one for small times or whenever a result must not depend
on ``k`` (see the documentation's conventions page).

Conventions are those of :class:`o3dheat.HeatKernel`: time ``exp(−λ t / 2)``,
``normalize="lambda2"`` divides the operator by its first non-zero eigenvalue (a few eigenpairs
are computed for that, once), a transfer function φ gives ``exp(−(t/2) φ(W⁻¹L))``, results are
per input vertex (0 at unreferenced vertices, welded copies share their vertex's value).
Accuracy: ``‖Φ_t f − result‖_W <= tol ‖f − f₀‖_W`` for every column and time, by the a
posteriori estimate of :mod:`o3dheat.spectral.krylov` (``f₀`` the W-mean of ``f`` on each connected part,
which is kept exactly); an answer whose estimate does not reach ``tol`` is never returned
(:class:`o3dheat.errors.ConvergenceError`).
"""

from __future__ import annotations

import hashlib
import time
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

from o3dheat import checks, parallel
from o3dheat.errors import ConvergenceError, MeshError, SolverError
from o3dheat.geometry import prepare
from o3dheat.geometry._loops import abs_row_sums, components

from . import fem
from .cache import memoized, memoized_has
from .kernel import NORMALIZATIONS, first_nonzero, mass_of, transfer_function
from .krylov import MIN_STEPS, propagate
from .linalg import analyze, factorize
from .memory import available_memory, check_memory
from .spectrum import shared_eigensolve

__all__ = ["heat_flow", "HeatFlow", "FlowReport", "shift", "shift_groups", "SPLIT_RANGE", "METHODS"]

#: the two forms of ``Φ_t f`` (``method=`` of the ``heat_smooth`` and ``feature_approx`` filters,
#: of :func:`o3dheat.pipelines.study.robustness_study` and ``o3dheat figure``): "spectral", the paper's
#: truncated ``X_k D_t X_kᵀ W f`` (:class:`o3dheat.HeatKernel`), the default; "exact", the full
#: kernel (:class:`HeatFlow`)
METHODS = ("spectral", "exact")
_OPERATORS = object()  # HeatFlow(mesh=_OPERATORS): made by from_operators

#: ratio τ_max/τ_min above which the times are split over two shifts (:func:`shift_groups`)
SPLIT_RANGE = 300.0
#: bytes per vertex allowed for the stored Krylov basis (at least 512 MiB, at most half the free
#: memory); vectors beyond are regenerated (one more solve each) instead of stored
BASIS_BYTES_PER_VERTEX = 2048


def shift_groups(taus):
    """The times (sorted, > 0) cut into groups, each served by one shift: a range wider than
    :data:`SPLIT_RANGE` is cut at ``τ_min R^0.45`` (and each part again): measured on 200k-vertex
    scans, four decades take about 97 solves with one shift and 69 cut in two (30 + 39; the
    second factor is made on the other core during the first part's solves, its analysis
    shared), three decades 88 and 61; below about 300 one shift is cheaper.

    Returns
    -------
    list of (k,) int ndarray
        Indices into ``taus``, in order.

    Examples
    --------
    >>> import numpy as np
    >>> from o3dheat.spectral.heatflow import shift_groups
    >>> [g.tolist() for g in shift_groups(np.geomspace(1.0, 1e4, 9))]
    [[0, 1, 2, 3], [4, 5, 6, 7, 8]]
    >>> [g.tolist() for g in shift_groups(np.geomspace(1.0, 10.0, 5))]
    [[0, 1, 2, 3, 4]]
    """
    taus = np.asarray(taus, dtype=np.float64)
    idx = np.arange(len(taus))
    if len(taus) == 0:
        return []
    span = np.log(taus[-1]) - np.log(taus[0]) if len(taus) > 1 else 0.0  # (logs: the ratio may overflow)
    if span <= np.log(SPLIT_RANGE):
        return [idx]
    cut = np.exp(np.log(taus[0]) + 0.45 * span)
    k = int(np.searchsorted(taus, cut))
    if k == 0 or k == len(taus):
        return [idx]
    return shift_groups(taus[:k]) + [g + k for g in shift_groups(taus[k:])]


def shift(tau_min, tau_max):
    """The shift ``γ`` of the factor ``W + γL`` for times ``τ`` (rate ``exp(−τλ)``) in
    ``[tau_min, tau_max]``.

    ``γ = τ_min · clip(0.3 (R/10)^0.45, 0.1, 8)``, ``R = τ_max/τ_min``, rounded to a quarter power
    of two (so that nearby ranges share a factor). Fitted to the steps needed for 1e-8 on
    irregular 20k-200k-vertex meshes, noisy and smooth fields: one time, best ``γ ≈ τ/10`` (17
    steps); the paper's ten scales (R = 10) ``γ ≈ 0.3 τ_min`` (22); R = 100, ``0.85 τ_min`` (41);
    four decades, ``6-8 τ_min`` (85); beyond, the largest times are past the decay of every mode
    and ``8 τ_min`` stays best.

    Examples
    --------
    >>> from o3dheat.spectral.heatflow import shift
    >>> round(shift(1.0, 10.0), 3), round(shift(1.0, 1e4), 3)
    (0.297, 6.727)
    """
    span = max(np.log(float(tau_max)) - np.log(float(tau_min)), 0.0)  # log R (R itself may overflow)
    factor = min(max(0.3 * np.exp(0.45 * (span - np.log(10.0))), 0.1), 8.0)
    return float(2.0 ** (np.round(4.0 * (np.log2(float(tau_min)) + np.log2(factor))) / 4.0))


@dataclass
class FlowReport:
    """How :meth:`HeatFlow.apply` computed its result.

    Attributes
    ----------
    tol : float
        The tolerance asked (relative, W-norm, of the non-constant part).
    times : (T,) float64 ndarray
        The times (paper convention).
    estimate : (c, T) float64 ndarray
        A posteriori error estimate per column and time, relative to ``‖f − f₀‖_W``; every
        entry is ``<= tol`` (0 at ``t = 0`` and for fields constant on each part).
    steps : (c,) int64 ndarray
        Solves (Lanczos steps) per column, over all shifts.
    shifts : list of (float, (k,) int ndarray)
        Each shift ``γ`` (times τ units) and the indices of the times it served.
    solves : int
        Right-hand sides solved in all (regenerated vectors included).
    timings : dict
        Seconds: "assemble" (0 when the operators were cached), "factorize", "solve".
    backend : str
        The factorization backend.

    Examples
    --------
    >>> import numpy as np, open3d as o3d, o3dheat
    >>> mesh = o3d.t.geometry.TriangleMesh.create_sphere(1.0, 16)
    >>> z = mesh.vertex.positions.numpy()[:, 2]
    >>> F, rep = o3dheat.heat_flow(mesh, z, [0.1, 1.0], return_report=True)
    >>> bool(rep.estimate.max() <= rep.tol), len(rep.shifts), rep.steps.tolist() == [rep.solves]
    (True, 1, True)
    """

    tol: float
    times: np.ndarray
    estimate: np.ndarray
    steps: np.ndarray
    shifts: list
    solves: int
    timings: dict = field(default_factory=dict)
    backend: str = ""

    def __repr__(self):
        return (f"FlowReport(tol={self.tol:g}, times={len(self.times)}, columns={len(self.steps)}, "
                f"solves={self.solves}, shifts={[round(g, 6) for g, _ in self.shifts]}, "
                f"estimate<={float(self.estimate.max(initial=0.0)):.2g}, backend={self.backend!r})")


class _Operators:
    """A mesh's operators for the flow: L, the mass W (None for the identity), the parts (the null
    space of L), a bound of the largest eigenvalue, the symbolic analysis of the factors' pattern
    (started in the background as soon as the pattern is known) and timings. Shared through the
    cache."""

    def __init__(self, L, W, mass, seconds=0.0, analysis=None, parts=None, symmetric=False):
        t0 = time.perf_counter()
        self.L, self.W = _csr(L, symmetric), None if W is None else _csr(W, symmetric)
        self.mass = mass
        self.parts, self.labels = connected_components(self.L, directed=False) if parts is None else parts
        self.d = np.ones(self.L.shape[0]) if self.W is None else np.asarray(self.W.sum(axis=1)).ravel()
        # Gershgorin on D⁻¹L, D the lumped mass (W itself when diagonal): the consistent mass is
        # >= D/4 element by element (each element's mass has eigenvalues |t|/12 x {1, 1, 4})
        rows = abs_row_sums(self.L.indptr, self.L.data)
        diagonal = self.W is None or self.W.nnz == np.count_nonzero(self.W.diagonal())
        if mass == "given" and not diagonal:  # no bound known for a mass built elsewhere
            self.lam_max = None
        else:
            self.lam_max = float(np.max(rows / np.maximum(self.d, 1e-300))) * (4.0 if mass == "consistent" else 1.0)
        self._analysis = analysis
        self.seconds = seconds + time.perf_counter() - t0

    @classmethod
    def of_mesh(cls, prep, mass):
        t0 = time.perf_counter()
        n = len(prep.V)
        pattern = fem.adjacency_pattern(prep.F, n)
        # the factors' ordering needs the pattern only: analysed on another core meanwhile
        analysis = parallel.background(analyze, sp.csc_matrix((np.ones(len(pattern[1])), pattern[1], pattern[0]),
                                                              shape=(n, n)))
        L, W, _ = fem.operators(prep.V, prep.F, mass, pattern=pattern)
        ops = cls(L, None if mass == "identity" else W, mass, time.perf_counter() - t0, None,
                  components(prep.F, n), symmetric=True)
        # waited for here: no job of this process's threads is left in the cache (a forked child
        # would wait for it forever)
        ops._analysis = analysis.result()
        ops.seconds = time.perf_counter() - t0
        return ops

    def shifted(self, gamma):
        """``W + γL`` (CSC: symmetric), on L's pattern when W's is the same or diagonal."""
        L, W = self.L, self.W
        n = L.shape[0]
        if W is not None and W.nnz == L.nnz and np.array_equal(W.indptr, L.indptr) and np.array_equal(W.indices, L.indices):
            data = W.data + gamma * L.data
        elif W is None or W.nnz == sp.csr_matrix(sp.diags(W.diagonal())).nnz:
            rows = np.repeat(np.arange(n), np.diff(L.indptr))
            diagonal = np.flatnonzero(L.indices == rows)
            if len(diagonal) != n:  # a vertex without a diagonal entry in L: the general sum
                return sp.csc_matrix((sp.identity(n) if W is None else W) + gamma * L)
            data = gamma * L.data
            data[diagonal] += 1.0 if W is None else W.diagonal()
        else:
            return sp.csc_matrix(W + gamma * L)
        return sp.csc_matrix((data, L.indices, L.indptr), shape=(n, n))

    @property
    def analysis(self):
        """The symbolic analysis of the factors' pattern (None: each factorization analyses)."""
        return self._analysis

    @property
    def nbytes(self):
        total = self.d.nbytes + self.labels.nbytes
        for M in (self.L, self.W):
            if M is not None:
                total += M.data.nbytes + M.indices.nbytes + M.indptr.nbytes
        return total


def _unit_columns(F):
    """``(F / p, p)``: each column divided by a power of two ``p`` that brings its largest value
    near 1 when it lies outside [2^-500, 2^500] (exact; ``p = 1`` for ordinary fields), so that
    W-norms neither overflow nor underflow."""
    top = np.max(np.abs(F), axis=0) if F.size else np.zeros(F.shape[1])
    p = np.ones(F.shape[1])
    far = (top > 0) & ((top < 2.0**-500) | (top > 2.0**500))
    p[far] = 2.0 ** np.round(np.log2(top[far]))
    return (F / p if far.any() else F), p


def _null_parts(L):
    """``(parts, labels)``: the connected parts of L's graph on which the constants are in L's
    null space (``L 1_p = 0`` to rounding), numbered; -1 for the vertices of the other parts (a
    Dirichlet boundary, a shifted operator: no null vector there)."""
    count, labels = connected_components(L, directed=False)
    rows = np.asarray(abs(L).sum(axis=1)).ravel()
    residual = np.abs(np.bincount(labels, weights=np.asarray(L.sum(axis=1)).ravel(), minlength=count))
    scale = np.bincount(labels, weights=rows, minlength=count)
    null = residual <= 1e-12 * np.maximum(scale, 1e-300)
    number = np.full(count, -1, np.int64)
    number[null] = np.arange(int(null.sum()))
    return int(null.sum()), number[labels]


def _csr(M, symmetric=False):
    """M as a float64 CSR matrix; a CSC one known to be symmetric (the operators of
    :mod:`o3dheat.spectral.fem`) reuses its arrays (they are those of its transpose)."""
    if symmetric and sp.isspmatrix_csc(M) and M.dtype == np.float64:
        return sp.csr_matrix((M.data, M.indices, M.indptr), shape=M.shape)
    return sp.csr_matrix(M, dtype=np.float64)


def _geometry_key(prep, mass):
    h = hashlib.sha256()
    h.update(np.ascontiguousarray(prep.V, dtype=np.float64).tobytes())
    h.update(np.ascontiguousarray(prep.F, dtype=np.int64).tobytes())
    h.update(f"{prep.V.shape}{prep.F.shape}|{mass}".encode())
    return h.hexdigest()[:32]


class _Shifted:
    """A factor of ``W + γL`` with its size, for the cache."""

    def __init__(self, ops, gamma, backend):
        t0 = time.perf_counter()
        analysis = ops.analysis if backend in ("auto", "cholmod") else None
        self.factor = factorize(ops.shifted(gamma), backend=backend, analysis=analysis)
        self.seconds = time.perf_counter() - t0

    @property
    def nbytes(self):
        return int(getattr(self.factor, "nbytes", 0))


class HeatFlow:
    """The full heat kernel of a mesh, ``K_t = exp(−(t/2) W⁻¹L)``, applied without eigenpairs.

    A stateful twin of :func:`heat_flow` for many fields and times on one mesh: the operators and
    the factors are built once (and shared with later HeatFlows of the same geometry and mass,
    unless ``cache=False``).

    Parameters
    ----------
    mesh : o3d.t.geometry.TriangleMesh, o3d.geometry.TriangleMesh or (V, F)
        Repaired as by :func:`o3dheat.geometry.welding.prepare` (welded duplicates, dropped degenerate faces).
    variant : str
        A key of :data:`o3dheat.spectral.kernel.VARIANTS`: its mass ``W`` (consistent ``B`` for the paper's
        "weighted" kernel, ``I`` for "linear", lumped, Voronoi).
    normalize : None or str
        One of :data:`o3dheat.spectral.kernel.NORMALIZATIONS`; "lambda2" uses ``W⁻¹L / λ_2``, the
        scale-invariant kernel (λ_2 from a small eigensolve, once).
    transfer : callable or sequence of float, optional
        A transfer function φ (§2.3), as for :class:`o3dheat.HeatKernel`: ``exp(−(t/2) φ(W⁻¹L))``.
        φ must be bounded below on ``[0, ∞)`` (a polynomial: a positive leading coefficient), or
        the full kernel does not exist (it amplifies the highest frequencies without bound).
    backend : str
        Factorization backend (:func:`o3dheat.spectral.linalg.factorize`).
    cache : bool
        Share the operators and factors through the in-memory cache.
    tol : float
        The default tolerance of :meth:`apply` (so that a HeatFlow stands in for a
        :class:`o3dheat.HeatKernel` in :func:`o3dheat.scale_space` and
        :func:`o3dheat.feature_driven`).

    Examples
    --------
    >>> import numpy as np, open3d as o3d, o3dheat
    >>> mesh = o3d.t.geometry.TriangleMesh.create_sphere(1.0, 16)
    >>> flow = o3dheat.HeatFlow(mesh)
    >>> xyz = mesh.vertex.positions.numpy()
    >>> F = flow.apply(xyz, [0.1, 1.0])                  # three fields, two times: (n, 3, 2)
    >>> F.shape, bool(np.allclose(flow.apply(np.ones(flow.n), 5.0), 1.0))
    ((482, 3, 2), True)
    """

    def __init__(self, mesh, variant="weighted", normalize=None, transfer=None, backend="auto", cache=True,
                 tol=1e-8):
        mass = mass_of(variant)
        self.tol = checks.tolerance(tol)
        if not (normalize is None or isinstance(normalize, str)) or normalize not in NORMALIZATIONS:
            raise MeshError(f"unknown normalize {normalize!r}: use one of {', '.join(map(repr, NORMALIZATIONS))}")
        self.variant, self.normalize, self.transfer = variant, normalize, transfer
        self._phi = transfer_function(transfer)
        self.backend, self.cache = backend, bool(cache)
        self._lambda2 = None
        self._local = {}
        if mesh is _OPERATORS:  # from_operators: set by the caller
            return
        self._prep = prepare(mesh)
        self._key = _geometry_key(self._prep, mass)
        t0 = time.perf_counter()
        self._ops = self._cached(("heatflow-operators", self._key), lambda: _Operators.of_mesh(self._prep, mass))
        self._assembled = time.perf_counter() - t0
        if self._phi is not None and self.normalize is None:
            self._check_transfer(1.0)  # with normalize, once λ_2 is known (first apply)

    @classmethod
    def from_operators(cls, L, W, normalize=None, transfer=None, backend="auto", tol=1e-8):
        """The full kernel ``exp(−(t/2) W⁻¹L)`` of operators built elsewhere (for example
        robust-laplacian's point-cloud Laplacian and mass), like
        :func:`o3dheat.spectral.spectrum.eigensolve_operators`: no faces, no repairs, not cached.

        Parameters
        ----------
        L : (n, n) sparse matrix
            Symmetric positive semi-definite, its null space the constants of each connected part
            of its graph (a Laplacian).
        W : (n, n) sparse matrix or None
            Symmetric positive definite mass; None for the identity.
        normalize, transfer, backend, tol
            As for :class:`HeatFlow`.

        Examples
        --------
        >>> import numpy as np, scipy.sparse as sp, o3dheat
        >>> L = sp.diags([[1., 2, 2, 1], [-1., -1, -1], [-1., -1, -1]], [0, 1, -1])   # a path graph
        >>> flow = o3dheat.HeatFlow.from_operators(L, None)
        >>> g = flow.apply([1.0, 0, 0, 0], 100.0)
        >>> g.round(6).tolist()                              # the mean, at large times
        [0.25, 0.25, 0.25, 0.25]
        """
        from o3dheat.geometry import Prepared

        try:
            L = sp.csr_matrix(L, dtype=np.float64)
            W = None if W is None else sp.csr_matrix(W, dtype=np.float64)
        except (TypeError, ValueError) as e:
            raise MeshError(f"L and W must be sparse (or dense) matrices of numbers: {e}") from None
        n = L.shape[0]
        if L.shape != (n, n) or (W is not None and W.shape != (n, n)):
            raise MeshError(f"L and W must be square and of one size, got {L.shape} and {getattr(W, 'shape', None)}")
        for name, M in (("L", L), ("W", W)):
            if M is None:
                continue
            if not np.all(np.isfinite(M.data)):
                raise MeshError(f"{name} has NaN or infinite entries")
            if M.nnz and abs(M - M.T).max() > 1e-10 * abs(M).max():
                raise MeshError(f"{name} must be symmetric")
        if np.any(L.diagonal() < 0) or (W is not None and np.any(W.diagonal() <= 0)):
            raise MeshError("L must be positive semi-definite and W positive definite (a negative diagonal entry)")
        flow = cls(_OPERATORS, variant="weighted", normalize=normalize, transfer=transfer, backend=backend,
                   cache=False, tol=tol)
        flow.variant = "given"
        flow._prep = Prepared(np.zeros((n, 3)), np.zeros((0, 3), np.int64), np.arange(n), n)
        flow._key = None
        flow._ops = _Operators(L, W, "given", parts=_null_parts(L))
        flow._assembled = flow._ops.seconds
        return flow

    def __repr__(self):
        return (f"HeatFlow(n={self.n}, variant={self.variant!r}, normalize={self.normalize!r}, "
                f"transfer={'yes' if self.transfer is not None else None})")

    def _cached(self, key, compute):
        """``compute()`` once per key: shared through the in-memory cache, or kept by this
        HeatFlow alone (``cache=False``)."""
        if self.cache:
            return memoized(key, compute)
        if key not in self._local:
            self._local[key] = compute()
        return self._local[key]

    @property
    def n(self):
        """Number of vertices of the input mesh (results have this many rows).

        Examples
        --------
        >>> import open3d as o3d, o3dheat
        >>> o3dheat.HeatFlow(o3d.t.geometry.TriangleMesh.create_sphere(1.0, 8)).n
        114
        """
        return self._prep.n_input

    @property
    def faces(self):
        """(m, 3) int64: the faces the operators are built on, in the input's vertex numbering
        (what the topology of smoothed fields is computed on); None for :meth:`from_operators`.

        Examples
        --------
        >>> import open3d as o3d, o3dheat
        >>> o3dheat.HeatFlow(o3d.t.geometry.TriangleMesh.create_sphere(1.0, 8)).faces.shape
        (224, 3)
        """
        if self._key is None:
            return None  # operators built elsewhere
        return self._prep.keep[self._prep.F]

    @property
    def lambda2(self):
        """The first non-zero eigenvalue of ``L x = λ W x`` (units 1/length², or dimensionless
        for "linear"), computed once with :func:`o3dheat.spectral.spectrum.shared_eigensolve`.

        Examples
        --------
        >>> import open3d as o3d, o3dheat
        >>> round(o3dheat.HeatFlow(o3d.t.geometry.TriangleMesh.create_sphere(1.0, 20)).lambda2, 1)
        2.0
        """
        if self._lambda2 is None:
            self._lambda2 = first_nonzero(self._spectrum(self._ops.parts + 1).eigenvalues)
        return self._lambda2

    def _spectrum(self, k):
        """The smallest k eigenpairs of this flow's operators (shared, cached)."""
        prep, ops = self._prep, self._ops
        if self._key is None:  # operators built elsewhere
            from .spectrum import eigensolve_operators

            W = sp.identity(ops.L.shape[0]) if ops.W is None else ops.W
            return eigensolve_operators(ops.L, W, k=min(k, ops.L.shape[0]))
        return shared_eigensolve(prep.V, prep.F, k=min(k, len(prep.V)), mass=ops.mass)

    def _unit(self):
        """The factor of the operator: 1, or 1/λ_2 for normalize="lambda2"."""
        return 1.0 / self.lambda2 if self.normalize == "lambda2" else 1.0

    def _check_transfer(self, unit):
        """Refuse a transfer function whose full kernel does not exist: φ decreasing without bound
        at high frequencies (exp(−(t/2) φ) would amplify them more, the finer the mesh)."""
        coef = self._phi.coefficients
        if coef is not None:
            nz = np.flatnonzero(coef)
            if len(nz) and nz[-1] > 0 and coef[nz[-1]] < 0:
                raise MeshError(f"the transfer polynomial's leading coefficient is negative ({coef[nz[-1]]:g}): "
                                "exp(-(t/2) φ(λ)) grows without bound as λ grows, so the full kernel does not "
                                "exist; use the spectral kernel (o3dheat.HeatKernel), which truncates it")
            return
        if self._ops.lam_max is None:  # a non-diagonal mass built elsewhere: no bound to sample up to
            return
        top = self._ops.lam_max * unit  # above every (normalised) eigenvalue
        lam = np.concatenate([[0.0], np.geomspace(max(top * 1e-12, 1e-300), top, 400)])
        phi = self._phi(lam)
        low = phi[lam <= 0.1 * top]
        if phi[-1] < phi[-40] and phi[-1] < low.min() - 1e-12 * max(np.abs(phi).max(), 1e-300):
            raise MeshError(f"the transfer function decreases to {phi[-1]:.3g} at λ = {top:.3g} (the top of this "
                            "mesh's spectrum), below its values at low frequencies: exp(-(t/2) φ(λ)) amplifies "
                            "the finest details more, the finer the mesh, so the full kernel does not converge; "
                            "use the spectral kernel (o3dheat.HeatKernel), which truncates it")

    def _rates(self, times):
        """``(taus, rates, null_rate, scale)`` for :func:`o3dheat.spectral.krylov.propagate`: ``exp(−τ
        rates(λ))`` is the kernel at each time, λ the eigenvalues of W⁻¹L; ``scale`` converts
        τ to the times of the rate λ (what the shift is chosen for: φ(x) ≈ x assumed)."""
        unit = self._unit()
        if self._phi is None:
            return 0.5 * times * unit, None, 0.0, 1.0
        phi = self._phi
        if self.normalize is not None:
            self._check_transfer(unit)
        return 0.5 * times, (lambda lam: phi(lam * unit)), float(phi(np.zeros(1))[0]), unit

    def _basis_bytes(self):
        free = available_memory()
        want = max(BASIS_BYTES_PER_VERTEX * len(self._prep.V), 512 * 2**20)
        return want if free is None else max(min(want, free // 2), 64 * 2**20)

    def apply(self, f, t, tol=None, *, return_report=False, max_steps=1000):
        """``Φ_t f = exp(−(t/2) W⁻¹L) f`` (the full kernel) at one or many times.

        Parameters
        ----------
        f : (n,) or (n, c) array_like
            Field(s) per vertex of the input mesh.
        t : float or (T,) array_like
            Times >= 0, paper convention (``exp(−λ t / 2)``), in any order.
        tol : float, optional
            Relative error asked, in (0, 1): ``‖Φ_t f − result‖_W <= tol ‖f − f₀‖_W`` for each
            column and time by the a posteriori estimate (``f₀``: the W-mean on each connected
            part). Default: the HeatFlow's ``tol``.
        return_report : bool
            Also return a :class:`FlowReport`.
        max_steps : int
            Most solves per column and shift before giving up (:class:`ConvergenceError`).

        Returns
        -------
        ndarray
            ``(n,)`` or ``(n, c)`` for a scalar ``t``; ``(n, T)`` or ``(n, c, T)`` for an array,
            like :meth:`o3dheat.HeatKernel.smooth`. With ``return_report``: ``(result, report)``.

        Raises
        ------
        MeshError
            A field with NaN or of the wrong shape, a negative time, ``tol`` outside (0, 1).
        ConvergenceError
            The estimate did not reach ``tol`` within ``max_steps`` (the message says how far).

        Examples
        --------
        >>> import numpy as np, open3d as o3d, o3dheat
        >>> mesh = o3d.t.geometry.TriangleMesh.create_sphere(1.0, 20)
        >>> z = mesh.vertex.positions.numpy()[:, 2]          # an eigenfunction: λ = 2 on the unit sphere
        >>> g = o3dheat.HeatFlow(mesh).apply(z, 1.0)
        >>> round(float(g @ z / (z @ z)), 2)                  # ≈ exp(−λ t / 2) = exp(−1)
        0.37
        """
        tol = self.tol if tol is None else checks.tolerance(tol)
        if isinstance(max_steps, bool) or not isinstance(max_steps, (int, np.integer)) or max_steps < MIN_STEPS:
            raise MeshError(f"max_steps must be an integer >= {MIN_STEPS} (the fewest steps an error estimate "
                            f"needs), got {max_steps!r}")
        f = checks.field(f, self.n)
        t_arr = checks.times(t)
        times = np.atleast_1d(t_arr)
        prep = self._prep
        F = prep.restrict(f).reshape(len(prep.V), -1)
        c, T = F.shape[1], len(times)
        check_memory(8 * (len(prep.V) + self.n) * c * T, f"the result ({c} fields x {T} times)",
                     "ask for fewer fields or times at once")
        U, report = self._flow(F, times, tol, int(max_steps))
        out = prep.expand(U.reshape(len(prep.V), c, T))
        if f.ndim == 1:
            out = out[:, 0, :]
        if t_arr.ndim == 0:
            out = out[..., 0]
        return (out, report) if return_report else out

    smooth = apply
    __call__ = apply

    def _flow(self, F, times, tol, max_steps):
        ops = self._ops
        r, c = F.shape
        T = len(times)
        taus, rates, null_rate, scale = self._rates(times)
        estimate = np.zeros((c, T))
        steps = np.zeros(c, dtype=np.int64)
        zero = np.flatnonzero(taus == 0)
        order = np.flatnonzero(taus > 0)
        order = order[np.argsort(taus[order], kind="stable")]
        # the result in the order of increasing times, each shift's times a slice of it: written
        # in place (no copy unless the times come unsorted or with zeros)
        in_order = len(zero) == 0 and np.array_equal(order, np.arange(T))
        U = np.empty((r, c, len(order)))
        shifts, solves, t_fac, t_sol = [], 0, 0.0, 0.0
        backend = ""
        groups = shift_groups(taus[order])
        gammas = [shift(scale * taus[order[g]].min(), scale * taus[order[g]].max()) for g in groups]
        null = (ops.labels, ops.d)
        F, units = _unit_columns(F)
        pending = None  # the next group's factor, made on another core during this group's solves
        try:
            for gi, (g, gamma) in enumerate(zip(groups, gammas, strict=True)):
                idx = order[g]
                tg = taus[idx]
                t0 = time.perf_counter()
                shifted = self._factor(gamma, pending)
                t1 = time.perf_counter()
                pending = None
                if (gi + 1 < len(groups) and not self._has_factor(gammas[gi + 1])
                        and self._room_for_another(shifted)):
                    pending = parallel.background(_Shifted, ops, gammas[gi + 1], self.backend)
                backend = shifted.factor.backend
                try:
                    _, info = propagate(shifted.factor.solve, ops.W, F, tg, gamma, null=null, tol=tol,
                                        max_steps=max_steps, rates=rates, basis_bytes=self._basis_bytes(),
                                        null_rate=null_rate, out=U[:, :, g[0]:g[-1] + 1],
                                        release=shifted.factor.release)
                finally:
                    shifted.factor.release()  # its solve workspaces (n x columns each): memory back now
                t_sol += time.perf_counter() - t1
                t_fac += t1 - t0
                if not info.converged.all():
                    bad = int(np.flatnonzero(~info.converged)[0])
                    worst = float(info.estimate[bad].max())
                    raise ConvergenceError(
                        f"the heat flow did not reach tol={tol:g} in {max_steps} steps (column {bad}: estimated "
                        f"relative error {worst:.2g} at times {times[idx].min():.4g}..{times[idx].max():.4g})"
                        + ("; the transfer function may make the kernel too rough to approximate"
                           if self._phi is not None else "; raise max_steps, or split the times"))
                estimate[:, idx] = info.estimate
                steps += info.steps
                solves += info.solves
                shifts.append((gamma, idx))
        finally:
            if pending is not None:  # no factorization left running behind an error
                try:
                    pending.result()
                except Exception:  # noqa: BLE001 - the error being raised is the one to report
                    pass
        if np.any(units != 1.0):
            with np.errstate(over="ignore", invalid="ignore"):
                U *= units[None, :, None]
            if not np.all(np.isfinite(U)):
                raise SolverError("Φ_t f exceeds the float64 range (|values| > 1.8e308): rescale the field")
        if not in_order:
            ordered, U = U, np.empty((r, c, T))
            U[:, :, order] = ordered
            U[:, :, zero] = (F * units)[:, :, None]
            del ordered
        timings = {"assemble": self._assembled, "factorize": t_fac, "solve": t_sol}
        self._assembled = 0.0  # later calls reuse the operators
        report = FlowReport(tol, times.copy(), estimate, steps, shifts, solves, timings, backend)
        return U, report

    def _room_for_another(self, shifted):
        """Whether a second factorization fits beside the current solves (its transient memory,
        about three times a factor, and a basis): else the next factor is made after them."""
        free = available_memory()
        return free is None or free > 3 * shifted.nbytes + self._basis_bytes()

    def _factor_key(self, gamma):
        return ("heatflow-factor", self._key, gamma, self.backend)

    def _has_factor(self, gamma):
        key = self._factor_key(gamma)
        return key in self._local or (self.cache and memoized_has(key))

    def _factor(self, gamma, pending=None):
        """The factor of ``W + γL``: cached, or made now (or by ``pending``, a background job)."""
        ops = self._ops
        return self._cached(self._factor_key(gamma),
                            (lambda: pending.result()) if pending is not None else (lambda: _Shifted(ops, gamma, self.backend)))

    def error(self, f, t, tol=None):
        """``ε∞ = ‖f − Φ_t f‖∞ / ‖f‖∞`` of the full kernel (0 when f = 0), like
        :meth:`o3dheat.HeatKernel.error`.

        Examples
        --------
        >>> import open3d as o3d, o3dheat
        >>> mesh = o3d.t.geometry.TriangleMesh.create_sphere(1.0, 16)
        >>> o3dheat.HeatFlow(mesh).error(mesh.vertex.positions.numpy()[:, 2], [0.01, 1.0]).round(2).tolist()
        [0.01, 0.63]
        """
        f = checks.field(f, self.n)
        if f.ndim != 1:
            raise MeshError("error() takes one scalar field (n,)")
        F = self.apply(f, t, tol=tol)
        nf = float(np.abs(f).max())
        d = np.abs(F - (f[:, None] if F.ndim == 2 else f)).max(axis=0)
        return d / nf if nf > 0 else d * 0.0

    def scales(self, count=10, grid="paper", k=100):
        """The scale grids of :meth:`o3dheat.HeatKernel.scales`, which are defined by a spectrum
        (``λ_k`` of ``k`` eigenpairs, and ``λ_2``): computed here with
        :func:`o3dheat.spectral.spectrum.shared_eigensolve` (cached; this costs the eigensolve that the
        flow itself does not need: pass explicit times to avoid it).

        Examples
        --------
        >>> import open3d as o3d, o3dheat
        >>> flow = o3dheat.HeatFlow(o3d.t.geometry.TriangleMesh.create_sphere(1.0, 16))
        >>> flow.scales(3, k=36).round(4).tolist()
        [0.01, 0.02, 0.03]
        """
        from .kernel import HeatKernel

        spec = self._spectrum(checks.count(k, "k"))
        variant = None if self._key is None else self.variant
        return HeatKernel(spec, variant=variant, normalize=self.normalize, transfer=self.transfer).scales(count, grid)


def heat_flow(mesh, f, t, *, variant="weighted", normalize=None, transfer=None, tol=1e-8,
              return_report=False, backend="auto"):
    """``Φ_t f`` with the full heat kernel ``exp(−(t/2) W⁻¹L)``: no eigenpairs, no truncation.

    The one-call twin of :class:`HeatFlow` (whose operators and factors it caches for later calls
    on the same geometry). See the module notes for the method, its cost and its accuracy.

    Parameters
    ----------
    mesh : Open3D mesh or (V, F)
        The surface, repaired for the FEM by :func:`o3dheat.geometry.welding.prepare` (not modified).
    f : (n,) or (n, c) array_like
        The field(s), one row per vertex.
    t : float or (T,) array_like
        Times >= 0, paper convention ``exp(−λ t / 2)``.
    variant, normalize, transfer, backend
        As for :class:`HeatFlow`.
    tol : float
        Relative W-norm error asked, in (0, 1) (see :meth:`HeatFlow.apply`).
    return_report : bool
        Also return the :class:`FlowReport` (solves, shifts, estimates, timings).

    Returns
    -------
    ndarray
        Shapes as :meth:`o3dheat.HeatKernel.smooth`: (n,), (n, T), (n, c) or (n, c, T).

    Examples
    --------
    >>> import numpy as np, open3d as o3d, o3dheat
    >>> mesh = o3d.t.geometry.TriangleMesh.create_torus()
    >>> z = mesh.vertex.positions.numpy()[:, 2]
    >>> F = o3dheat.heat_flow(mesh, z, [0.01, 0.1, 1.0])
    >>> F.shape, bool(np.all(np.abs(F).max(axis=0)[1:] < np.abs(F).max(axis=0)[:-1]))
    ((600, 3), True)
    """
    flow = HeatFlow(mesh, variant=variant, normalize=normalize, transfer=transfer, backend=backend, tol=tol)
    return flow.apply(f, t, return_report=return_report)
