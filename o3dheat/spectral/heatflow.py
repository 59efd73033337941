"""The full heat kernel without eigenpairs, ``Φ_t f = exp(−(t/2) W⁻¹L) f``: :func:`heat_flow`, :class:`HeatFlow`.

Entry points: :func:`heat_flow` (one call), :class:`HeatFlow` (many fields and times on one mesh;
:meth:`HeatFlow.from_operators` for operators built elsewhere), :class:`FlowReport`,
:data:`METHODS`; the shifts (:func:`shift_groups`, :func:`shift`) and the operators are set up in
:mod:`o3dheat.spectral._flow_setup`, the Krylov propagation is :mod:`o3dheat.spectral.krylov`.

Notes
-----
Why: the spectral kernel ``X_k D_t X_kᵀ W f`` of :class:`o3dheat.HeatKernel <o3dheat.spectral.kernel.HeatKernel>` is band-limited to
the ``k`` smallest eigenpairs. At the paper's scales ``t_i = (i/10)/λ_k`` the dropped eigenpairs
would keep ``exp(−λ_k t_1 / 2) = 95%`` of their weight in the full kernel, so there the truncation,
not ``t``, does the smoothing. The full kernel ``K_t = exp(−(t/2) W⁻¹L)`` is the one of eq.
(5)-(6) without truncation; ``W`` is the variant's mass (:data:`o3dheat.spectral.variants.VARIANTS`).

How: shift-and-invert Lanczos on sparse Cholesky factors of ``W + γL``, one per group of times,
kept with the mesh's operators in the in-memory cache (:func:`o3dheat.spectral.cache.memoized`);
the method, its cost (about 27 solves for the paper's ten scales, at any mesh size) and its
benchmarks are in the documentation's details (``docs/details/heatflow.md``), and why "spectral"
stays the default of the filters and the studies in its conventions page.

Conventions are those of :class:`o3dheat.HeatKernel <o3dheat.spectral.kernel.HeatKernel>`: time ``exp(−λ t / 2)``,
``normalize="lambda2"`` divides the operator by its first non-zero eigenvalue (a few eigenpairs
are computed for that, once), a transfer function φ gives ``exp(−(t/2) φ(W⁻¹L))``, results are
per input vertex (0 at unreferenced vertices, welded copies share their vertex's value).
Accuracy: ``‖Φ_t f − result‖_W <= tol ‖f − f₀‖_W`` for every column and time, by the a
posteriori estimate of :mod:`o3dheat.spectral.krylov` (``f₀`` the W-mean of ``f`` on each
connected part, which is kept exactly); an answer whose estimate does not reach ``tol`` is never
returned (:class:`o3dheat.errors.ConvergenceError`). With a transfer function the estimate is a
rigorous a priori bound instead, for the shift chosen for φ
(:func:`o3dheat.spectral._flow_setup.transfer_plan`; it needs ``λ_2``, a small eigensolve, once
per mesh), and the error is relative to ``exp(−(t/2) φ(0)) ‖f − f₀‖_W`` (the factor of the
constants, applied exactly: larger than 1 when ``φ(0) < 0``).
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence

import numpy as np
import scipy.sparse as sp

from o3dheat import checks, parallel
from o3dheat.errors import MeshError, OutOfMemory
from o3dheat.geometry import Prepared, prepare
from o3dheat.memory import available_memory, check_memory
from o3dheat.typing import FieldLike, MeshLike, TimesLike

from ._flow_setup import (
    SPLIT_RANGE,
    FlowReport,
    Operators,
    Shifted,
    check_converged,
    check_operators,
    check_plan,
    check_transfer,
    finish,
    geometry_key,
    null_parts,
    shift,
    shift_groups,
    time_order,
    transfer_plan,
    unit_columns,
)
from .cache import forget, memoized, memoized_has, memory_cache_max_bytes
from .kernel import NORMALIZATIONS, HeatKernel, first_nonzero, mass_of, transfer_function
from .krylov import MIN_STEPS, propagate
from .spectrum import eigensolve_operators, shared_eigensolve

__all__ = ["heat_flow", "HeatFlow", "FlowReport", "shift", "shift_groups", "SPLIT_RANGE", "METHODS"]

#: the two forms of ``Φ_t f`` (``method=`` of the ``heat_smooth`` and ``feature_approx`` filters,
#: of :func:`o3dheat.pipelines.study.robustness_study` and ``o3dheat figure``): "spectral", the paper's
#: truncated ``X_k D_t X_kᵀ W f`` (:class:`o3dheat.HeatKernel <o3dheat.spectral.kernel.HeatKernel>`), the default; "exact", the full
#: kernel (:class:`HeatFlow`)
METHODS = ("spectral", "exact")
_OPERATORS = object()  # HeatFlow(mesh=_OPERATORS): made by from_operators

#: Lanczos vectors kept per column for the result (2 KiB per vertex and column; four decades of t
#: take about 85 steps), within half the memory left free by the result and the steps' work
#: arrays; vectors beyond are regenerated (one more solve each) instead of stored
KEPT_STEPS = 256
#: Lanczos steps per column counted by :meth:`HeatFlow.peak_bytes` for the stored basis of a group of
#: times spanning a ratio R: ``a + b log10(R)`` (measured at tol 1e-8: 17 for one time, 22-27 for
#: R = 10, 41 for R = 100, 31-39 for R = 60-300)
ESTIMATED_STEPS = (17, 10)
#: the stored basis is kept within at least this many bytes, whatever the memory left (the rest of
#: its vectors regenerated: one more solve each)
LEAST_BASIS_BYTES = 64 * 2**20


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
        A key of :data:`o3dheat.spectral.variants.VARIANTS`: its mass ``W`` (consistent ``B`` for the paper's
        "weighted" kernel, ``I`` for "linear", lumped, Voronoi).
    normalize : None or str
        One of :data:`o3dheat.spectral.variants.NORMALIZATIONS`; "lambda2" uses ``W⁻¹L / λ_2``, the
        scale-invariant kernel (λ_2 from a small eigensolve, once).
    transfer : callable or sequence of float, optional
        A transfer function φ (§2.3), as for :class:`o3dheat.HeatKernel <o3dheat.spectral.kernel.HeatKernel>`: ``exp(−(t/2) φ(W⁻¹L))``.
        φ must be bounded below on ``[0, ∞)`` (a polynomial: a positive leading coefficient), or
        the full kernel does not exist (it amplifies the highest frequencies without bound). Any
        such φ is certified (the module notes), non-analytic ones such as ``√λ`` included; one
        too rough on the mesh's spectrum to be is refused (:class:`~o3dheat.errors.ConvergenceError`).
    backend : str
        Factorization backend (:func:`o3dheat.spectral.linalg.factorize`).
    cache : bool
        Share the operators and factors through the in-memory cache.
    tol : float
        The default tolerance of :meth:`apply` (so that a HeatFlow stands in for a
        :class:`o3dheat.HeatKernel <o3dheat.spectral.kernel.HeatKernel>` in :func:`o3dheat.scale_space <o3dheat.topology.approximation.scale_space>` and
        :func:`o3dheat.feature_driven <o3dheat.topology.approximation.feature_driven>`).

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

    def __init__(self, mesh: MeshLike, variant: str = "weighted", normalize: str | None = None,
                 transfer: Callable | Sequence[float] | None = None, backend: str = "auto", cache: bool = True,
                 tol: float = 1e-8):
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
        self._key = geometry_key(self._prep, mass)
        t0 = time.perf_counter()
        self._ops = self._cached(("heatflow-operators", self._key), lambda: Operators.of_mesh(self._prep, mass))
        self._assembled = time.perf_counter() - t0
        if self._phi is not None and self.normalize is None:
            check_transfer(self._phi, self._ops.lam_max, 1.0)  # with normalize, once λ_2 is known (first apply)

    @classmethod
    def from_operators(cls, L: sp.spmatrix, W: sp.spmatrix | None, normalize: str | None = None,
                       transfer: Callable | Sequence[float] | None = None, backend: str = "auto",
                       tol: float = 1e-8) -> HeatFlow:
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
        L, W = check_operators(L, W)
        n = L.shape[0]
        flow = cls(_OPERATORS, variant="weighted", normalize=normalize, transfer=transfer, backend=backend,
                   cache=False, tol=tol)
        flow.variant = "given"
        flow._prep = Prepared(np.zeros((n, 3)), np.zeros((0, 3), np.int64), np.arange(n), n)
        flow._key = None
        flow._ops = Operators(L, W, "given", parts=null_parts(L))
        flow._assembled = flow._ops.seconds
        return flow

    def __repr__(self):
        return (f"HeatFlow(n={self.n}, variant={self.variant!r}, normalize={self.normalize!r}, "
                f"transfer={'yes' if self.transfer is not None else None})")

    def _cached(self, key, compute, room=0):
        """``compute()`` once per key: shared through the in-memory cache (``room``: the bytes it
        will need, made room for first), or kept by this HeatFlow alone (``cache=False``)."""
        if self.cache:
            return memoized(key, compute, room)
        if key not in self._local:
            self._local[key] = compute()
        return self._local[key]

    @property
    def n(self) -> int:
        """Number of vertices of the input mesh (results have this many rows).

        Examples
        --------
        >>> import open3d as o3d, o3dheat
        >>> o3dheat.HeatFlow(o3d.t.geometry.TriangleMesh.create_sphere(1.0, 8)).n
        114
        """
        return self._prep.n_input

    @property
    def faces(self) -> np.ndarray | None:
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
    def lambda2(self) -> float:
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
            W = sp.identity(ops.L.shape[0]) if ops.W is None else ops.W
            return eigensolve_operators(ops.L, W, k=min(k, ops.L.shape[0]))
        return shared_eigensolve(prep.V, prep.F, k=min(k, len(prep.V)), mass=ops.mass)

    def _unit(self):
        """The factor of the operator: 1, or 1/λ_2 for normalize="lambda2"."""
        return 1.0 / self.lambda2 if self.normalize == "lambda2" else 1.0

    def _rates(self, times):
        """``(taus, rates, null_rate)`` for :func:`o3dheat.spectral.krylov.propagate`: ``exp(−τ
        rates(λ))`` is the kernel at each time, λ the eigenvalues of W⁻¹L."""
        unit = self._unit()
        if self._phi is None:
            return 0.5 * times * unit, None, 0.0
        phi = self._phi
        if self.normalize is not None:
            check_transfer(self._phi, self._ops.lam_max, unit)
        return 0.5 * times, (lambda lam: phi(lam * unit)), float(phi(np.zeros(1))[0])

    def _plans(self, taus, groups, rates, null_rate, tol, max_steps, times):
        """A transfer function's :class:`~o3dheat.spectral._flow_setup.Plan` per group of times: its
        shift and a priori bound on the spectrum's interval ``[λ_2, λ_max]`` of W⁻¹L (λ_2 from a
        small eigensolve, with a margin of 1e-3 for its accuracy; λ_max by Gershgorin)."""
        top = np.inf if self._ops.lam_max is None else self._ops.lam_max
        try:
            low = 0.999 * self.lambda2
        except MeshError:  # no non-zero eigenvalue: the interval reaches the null space's
            low = 1e-12 * (top if np.isfinite(top) else 1.0)
        plans = [transfer_plan(lambda lam: rates(lam) - null_rate, taus[g], low, top, tol, max_steps) for g in groups]
        for plan, g in zip(plans, groups, strict=True):
            check_plan(plan, tol, max_steps, times[g], bounded=np.isfinite(top))
        return plans

    def _basis_bytes(self, c, T):
        """Bytes for the stored basis of ``c`` columns (the result has ``T`` times): see :data:`KEPT_STEPS`."""
        n = len(self._prep.V)
        want = 8 * n * c * KEPT_STEPS
        free = available_memory()
        if free is None:
            return want
        pending = 8 * n * c * (T + 8)  # the result, written after the steps, and the steps' arrays
        return max(min(want, (free - pending) // 2), LEAST_BASIS_BYTES)

    def release(self) -> None:
        """Give back the memory of this flow's factors: they leave the in-memory cache (and this
        HeatFlow), and are made again by a later :meth:`apply` that needs them; the operators stay.
        The cache keeps its newest result whatever its size, and a factor of a 10M-vertex mesh
        takes 5-9 GB.

        Examples
        --------
        >>> import open3d as o3d, o3dheat
        >>> mesh = o3d.t.geometry.TriangleMesh.create_sphere(1.0, 16)
        >>> flow = o3dheat.HeatFlow(mesh)
        >>> g = flow.apply(mesh.vertex.positions.numpy()[:, 2], 0.1)
        >>> flow.release(); bool(abs(flow.apply(mesh.vertex.positions.numpy()[:, 2], 0.1) - g).max() < 1e-12)
        True
        """
        forget(lambda key: isinstance(key, tuple) and key[:2] == ("heatflow-factor", self._key))
        for key in [k for k in self._local if k[0] == "heatflow-factor"]:
            del self._local[key]

    def peak_bytes(self, c: int = 1, t: TimesLike = 1.0, *, least: bool = False) -> int:
        """Estimated peak memory of :meth:`apply` with ``c`` fields at the times ``t``, in bytes,
        beyond what this HeatFlow holds (its operators).

        The factorization's peak (known from the symbolic analysis made with the operators,
        :attr:`o3dheat.spectral.linalg.Analysis.nbytes`) and, when the times make several groups
        (:func:`shift_groups`) and memory allows making the next factor during the current group's
        solves, the current factor beside it (``(8 + index bytes) nnz(L) + 48 n``); the stored
        basis of the widest group (:data:`ESTIMATED_STEPS`, within the basis' budget); the result
        (and its copy per input vertex when vertices were welded or set aside); with several groups,
        the current factor beside the next one where it is kept (made during its solves, or within
        the in-memory cache's budget); 32 bytes per vertex
        and field of work arrays, and 32 MiB. What the HeatFlow already holds (its operators and
        symbolic analysis: 230-580 bytes per vertex) is not counted: the memory left is measured
        after it was made. Calibrated against the peak of :meth:`apply` above the resident size
        before it, at 250k, 1M and 2M vertices, 1, 8 and 32 fields, 10 and 20 times, on a
        curvature-adaptive and a uniform mesh (``docs/details/large.md``): 4-33% above each. :meth:`apply` refuses
        what does not fit with :class:`~o3dheat.errors.OutOfMemory`, by the least it can run with
        (``least=True``).

        Parameters
        ----------
        c : int
            Fields (columns).
        t : float or (T,) array_like
            The times (paper convention).
        least : bool
            The least memory the flow can run with: the basis kept within 64 MiB and its other
            vectors regenerated (one more solve each: the flow then takes up to twice as long;
            :attr:`~o3dheat.spectral.krylov.Propagation.replayed` counts them), no factor made
            beside another. The basis is kept within half of the memory left once the factor
            is made, whatever this estimate.

        Returns
        -------
        int

        Examples
        --------
        >>> import numpy as np, open3d as o3d, o3dheat
        >>> flow = o3dheat.HeatFlow(o3d.t.geometry.TriangleMesh.create_sphere(1.0, 20))
        >>> ten, wide = np.geomspace(0.01, 0.1, 10), np.geomspace(1e-4, 1.0, 20)     # one decade, four
        >>> flow.peak_bytes(1, ten) < flow.peak_bytes(8, ten) < flow.peak_bytes(8, wide)
        True
        """
        c = checks.count(c, "c")
        times = np.atleast_1d(checks.times(t))
        n, T = len(self._prep.V), len(times)
        analysis = self._ops.analysis
        taus = np.sort(times[times > 0])
        groups = shift_groups(taus) if len(taus) else []
        factor = analysis.nbytes if analysis is not None else 0
        a, b = ESTIMATED_STEPS
        steps = max([a + b * np.log10(taus[g[-1]] / taus[g[0]]) for g in groups], default=0.0)
        expanded = self._prep.weld is not None or len(self._prep.keep) != self._prep.n_input  # expand copies
        basis = min(8 * n * c * steps, LEAST_BASIS_BYTES if least else self._basis_bytes(c, T))
        peak = factor + basis + 8 * n * c * T * (2 if expanded else 1) + 32 * c * n + 32 * 2**20
        if len(groups) > 1 and analysis is not None and not least:
            # the current factor beside the next one: made during its solves (as _room_for_another),
            # or kept by the cache (within its budget) or by a flow without the cache
            kept = (16 if analysis.wide else 12) * analysis.lnz + 48 * n
            if self._room_beside(factor, c, T) or not self.cache or kept <= memory_cache_max_bytes():
                peak += kept
        return int(peak)

    def apply(self, f: FieldLike, t: TimesLike, tol: float | None = None, *, return_report: bool = False,
              max_steps: int = 1000) -> np.ndarray | tuple[np.ndarray, FlowReport]:
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
            part); with a transfer function, by an a priori bound, relative to ``exp(−(t/2) φ(0))
            ‖f − f₀‖_W`` (see the module notes). Default: the HeatFlow's ``tol``.
        return_report : bool
            Also return a :class:`FlowReport`.
        max_steps : int
            Most solves per column and shift before giving up (:class:`ConvergenceError`).

        Returns
        -------
        ndarray
            ``(n,)`` or ``(n, c)`` for a scalar ``t``; ``(n, T)`` or ``(n, c, T)`` for an array,
            like :meth:`o3dheat.HeatKernel.smooth <o3dheat.spectral.kernel.HeatKernel.smooth>`. With ``return_report``: ``(result, report)``.

        Raises
        ------
        MeshError
            A field with NaN or of the wrong shape, a negative time, ``tol`` outside (0, 1).
        ConvergenceError
            The estimate did not reach ``tol`` within ``max_steps`` (the message says how far).
        OutOfMemory
            :meth:`peak_bytes` exceeds the memory left even after this flow's cached factors were
            released (:meth:`release`; they are let go only when the estimate does not fit).

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
        # by the least it can run with (the basis regenerated where it does not fit); this flow's
        # own factors, like the cache, give their memory back before a refusal
        check_memory(self.peak_bytes(c, times, least=True), f"the heat flow of {self.n:,} vertices, {c} field(s) x "
                     f"{T} times", "ask for fewer fields or times at once, decimate the mesh, or use more memory",
                     release=self.release)
        try:
            U, report = self._flow(F, times, tol, int(max_steps))
        except MemoryError as e:  # numba's or numpy's allocation: said as the eigensolver says it
            raise OutOfMemory(f"out of memory in the heat flow of {self.n:,} vertices and {F.shape[1]} field(s) "
                              f"({e}): fewer fields or times at once, a decimated mesh, or more memory") from e
        out = prep.expand(U.reshape(len(prep.V), c, T))
        if f.ndim == 1:
            out = out[:, 0, :]
        if t_arr.ndim == 0:
            out = out[..., 0]
        return (out, report) if return_report else out

    smooth = apply
    __call__ = apply

    def _flow(self, F, times, tol, max_steps):
        """``(U, report)``: the flow of the columns ``F`` (on the prepared vertices) at ``times``,
        one factor per group of times (:func:`shift_groups`), the next one made on another core
        during the current group's solves."""
        c, T = F.shape[1], len(times)
        taus, rates, null_rate = self._rates(times)
        estimate = np.zeros((c, T))
        steps = np.zeros(c, dtype=np.int64)
        zero, order, in_order = time_order(taus)
        # the result in the order of increasing times, each shift's times a slice of it: written
        # in place (no copy unless the times come unsorted or with zeros)
        U = np.empty((F.shape[0], c, len(order)))
        shifts, solves, t_fac, t_sol = [], 0, 0.0, 0.0
        backend = ""
        groups = shift_groups(taus[order])
        if rates is None:
            plans = [None] * len(groups)
            gammas = [shift(taus[order[g]].min(), taus[order[g]].max()) for g in groups]
        else:  # a transfer function: its own shifts, and an a priori bound as the estimate
            plans = self._plans(taus, [order[g] for g in groups], rates, null_rate, tol, max_steps, times)
            gammas = [p.gamma for p in plans]
        F, units = unit_columns(F)
        pending = None  # the next group's factor, made on another core during this group's solves
        try:
            for gi, (g, gamma, plan) in enumerate(zip(groups, gammas, plans, strict=True)):
                idx = order[g]
                t0 = time.perf_counter()
                shifted = self._factor(gamma, pending)
                t1 = time.perf_counter()
                pending = self._next_factor(gammas, gi, shifted, c, T)
                backend = shifted.factor.backend
                info = self._propagate(shifted, F, taus[idx], gamma, U[:, :, g[0]:g[-1] + 1], tol, max_steps,
                                       rates, null_rate, None if plan is None else plan.bound)
                t_sol += time.perf_counter() - t1
                t_fac += t1 - t0
                shifted = None  # this group's factor: freed before the next is made, unless cached
                check_converged(info, tol, max_steps, times[idx], self._phi is not None)
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
        U = finish(U, F, units, order, zero, in_order)
        timings = {"assemble": self._assembled, "factorize": t_fac, "solve": t_sol}
        self._assembled = 0.0  # later calls reuse the operators
        report = FlowReport(tol, times.copy(), estimate, steps, shifts, solves, timings, backend)
        return U, report

    def _next_factor(self, gammas, gi, shifted, c, T):
        """The factor of the group after ``gi``, started on another core (None when it is cached,
        there is none, or it would not fit beside the current solves)."""
        if (gi + 1 < len(gammas) and not self._has_factor(gammas[gi + 1])
                and self._room_for_another(shifted, c, T)):
            return parallel.background(Shifted, self._ops, gammas[gi + 1], self.backend)
        return None

    def _propagate(self, shifted, F, taus, gamma, out, tol, max_steps, rates, null_rate, bound=None):
        """One group's propagation into ``out`` (:func:`o3dheat.spectral.krylov.propagate`), the
        factor's solve workspaces given back after it."""
        ops = self._ops
        try:
            _, info = propagate(shifted.factor.solve, ops.W, F, taus, gamma, null=(ops.labels, ops.d), tol=tol,
                                max_steps=max_steps, rates=rates, null_rate=null_rate,
                                basis_bytes=self._basis_bytes(F.shape[1], out.shape[2]), out=out,
                                release=shifted.factor.release, bound=bound)
        finally:
            shifted.factor.release()  # its solve workspaces (n x columns each): memory back now
        return info

    def _room_for_another(self, shifted, c, T):
        """Whether a second factorization fits beside the current solves with room to spare (twice
        its peak, known from the symbolic analysis, else three times a factor, and a basis): else
        the next factor is made after them, once the current one is freed (and dropped from the
        cache when it does not fit its budget): a 10M-vertex factor is 5-9 GB."""
        analysis = self._ops.analysis
        return self._room_beside(analysis.nbytes if analysis is not None else 3 * shifted.nbytes, c, T)

    def _room_beside(self, peak, c, T):
        """Whether a factorization of ``peak`` bytes and a basis fit twice over in the memory left."""
        free = available_memory()
        return free is None or free > 2 * (peak + self._basis_bytes(c, T))

    def _factor_key(self, gamma):
        return ("heatflow-factor", self._key, gamma, self.backend)

    def _has_factor(self, gamma):
        key = self._factor_key(gamma)
        return key in self._local or (self.cache and memoized_has(key))

    def _factor(self, gamma, pending=None):
        """The factor of ``W + γL``: cached, or made now (or by ``pending``, a background job)."""
        ops = self._ops
        if pending is not None:
            return self._cached(self._factor_key(gamma), lambda: pending.result())
        room = ops.analysis.nbytes if ops.analysis is not None else 0
        return self._cached(self._factor_key(gamma), lambda: Shifted(ops, gamma, self.backend), room)

    def error(self, f: FieldLike, t: TimesLike, tol: float | None = None) -> float | np.ndarray:
        """``ε∞ = ‖f − Φ_t f‖∞ / ‖f‖∞`` of the full kernel (0 when f = 0), like
        :meth:`o3dheat.HeatKernel.error <o3dheat.spectral.kernel.HeatKernel.error>`.

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

    def scales(self, count: int = 10, grid: str = "paper", k: int = 100) -> np.ndarray:
        """The scale grids of :meth:`o3dheat.HeatKernel.scales <o3dheat.spectral.kernel.HeatKernel.scales>`, which are defined by a spectrum
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
        spec = self._spectrum(checks.count(k, "k"))
        variant = None if self._key is None else self.variant
        return HeatKernel(spec, variant=variant, normalize=self.normalize, transfer=self.transfer).scales(count, grid)


def heat_flow(mesh: MeshLike, f: FieldLike, t: TimesLike, *, variant: str = "weighted", normalize: str | None = None,
              transfer: Callable | Sequence[float] | None = None, tol: float = 1e-8, return_report: bool = False,
              backend: str = "auto") -> np.ndarray | tuple[np.ndarray, FlowReport]:
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
        Shapes as :meth:`o3dheat.HeatKernel.smooth <o3dheat.spectral.kernel.HeatKernel.smooth>`: (n,), (n, T), (n, c) or (n, c, T).

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
