"""The heat kernels of the paper and what is computed with them: :class:`HeatKernel`, :func:`heat_kernel`.

Entry points: :func:`heat_kernel` (a mesh's kernel), :class:`HeatKernel` (on a
:class:`~o3dheat.spectral.spectrum.Spectrum`: the feature map Φ_t, heat kernel signatures, the paper's scales,
approximation errors, the canonic basis, the inverse, truncation bounds). The variants and the
other lists (:data:`~o3dheat.spectral.variants.VARIANTS`, :data:`~o3dheat.spectral.variants.GRIDS`,
:data:`~o3dheat.spectral.variants.HKS_FORMS`, :data:`~o3dheat.spectral.variants.NORMALIZATIONS`) are
defined once in :mod:`o3dheat.spectral.variants`.

Notes
-----
Time follows the paper: ``K_t = X D_t Xᵀ W`` with ``D_t = diag(exp(-φ(λ_i) t / 2))`` (eq. (6)),
``φ(λ) = λ`` unless a transfer function is given (§2.3), and ``λ_i`` divided by the first non-zero
eigenvalue when ``normalize="lambda2"`` (§2.2: the kernel is then scale invariant). Peers such as
LaPy and Sun et al. write ``exp(-λ t)``: ``t_paper = 2 t_peer``. Each variant is the heat kernel of
its own eigenproblem ``L x = λ W x`` (see :mod:`o3dheat.spectral.variants`).

Everything works on the truncated spectrum (``k`` eigenpairs): ``Φ_t f = X_k D_t X_kᵀ W f`` costs
``O(k n)`` per scale and field.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from functools import cached_property
from typing import Any

import numpy as np

from o3dheat import checks
from o3dheat.errors import MeshError, SolverError
from o3dheat.typing import FieldLike, MeshLike, TimesLike

from . import _truncation, signatures, spectrum
from .spectrum import Spectrum, all_zero
from .variants import (
    GRIDS,
    HKS_DEFAULT,
    HKS_FORMS,
    NORMALIZATIONS,
    first_nonzero,
    mass_of,
    transfer_function,
    variant_of_mass,
)

__all__ = ["HeatKernel", "heat_kernel"]


def heat_kernel(mesh: MeshLike, k: int = 100, variant: str = "weighted", normalize: str | None = None,
                transfer: Callable | Sequence[float] | None = None, **eigensolve_options: Any) -> HeatKernel:
    """The heat kernel ``variant`` of a mesh: its eigenproblem solved with the right mass, then
    :class:`HeatKernel`.

    Parameters
    ----------
    mesh : Open3D mesh or (V, F)
        The surface, repaired for the FEM by :func:`o3dheat.geometry.welding.prepare` (not modified).
    k : int
        Eigenpairs.
    variant : str
        A key of :data:`~o3dheat.spectral.variants.VARIANTS`.
    normalize, transfer
        As for :class:`HeatKernel`.
    **eigensolve_options
        Passed to :func:`o3dheat.eigensolve <o3dheat.spectral.spectrum.eigensolve>` (``cache``, ``method``, ``tol``...; not ``mass``).

    Returns
    -------
    HeatKernel

    Examples
    --------
    >>> import numpy as np, open3d as o3d, o3dheat
    >>> mesh = o3d.t.geometry.TriangleMesh.create_sphere(1.0, 16)
    >>> K = o3dheat.heat_kernel(mesh, k=20, variant="linear")     # eigenpairs of L x = λ x
    >>> K.spectrum.mass_kind, bool(np.allclose(K.smooth(np.ones(K.n), 3.0), 1.0))
    ('identity', True)
    """
    mass = mass_of(variant)
    if "mass" in eigensolve_options:
        raise MeshError("heat_kernel chooses the mass from the variant: do not pass mass=")
    spec = spectrum.eigensolve(mesh, k=k, mass=mass, **eigensolve_options)  # looked up at the call: patchable
    return HeatKernel(spec, variant=variant, normalize=normalize, transfer=transfer)




class HeatKernel:
    """Heat kernel ``K_t = X D_t Xᵀ W`` built on a :class:`~o3dheat.spectral.spectrum.Spectrum`.

    Parameters
    ----------
    spectrum : Spectrum
        From :func:`o3dheat.eigensolve <o3dheat.spectral.spectrum.eigensolve>`.
    variant : None or str
        The kernel, a key of :data:`~o3dheat.spectral.variants.VARIANTS`, whose mass must be the spectrum's: None takes the
        (first) variant of ``spectrum.mass_kind``; a variant whose mass differs is refused
        (compute the spectrum with ``eigensolve(mesh, k, mass=mass_of(variant))``, or use
        :func:`heat_kernel`). A spectrum of :func:`o3dheat.spectral.spectrum.eigensolve_operators` (mass
        "given") takes None or "weighted" (its own mass as the weight).
    normalize : None or str
        One of :data:`NORMALIZATIONS`: "lambda2" divides the eigenvalues by the first non-zero
        one (scale-invariant kernel, §2.2).
    transfer : callable or sequence of float, optional
        Transfer function φ (§2.3): a vectorised callable ``φ(λ)`` or polynomial coefficients in
        increasing degree ``c0 + c1 λ + c2 λ² ...``. Values must be finite; a negative φ amplifies.

    Examples
    --------
    >>> import numpy as np, open3d as o3d, o3dheat
    >>> mesh = o3d.t.geometry.TriangleMesh.create_sphere(1.0, 20)
    >>> K = o3dheat.HeatKernel(o3dheat.eigensolve(mesh, k=30))
    >>> f = mesh.vertex.positions.numpy()[:, 2]
    >>> F = K.smooth(f, K.scales())          # the paper's 10 scales, shape (n, 10)
    >>> F.shape, bool(np.abs(F[:, -1]).max() < np.abs(f).max())
    ((762, 10), True)
    """

    def __init__(self, spectrum: Spectrum, variant: str | None = None, normalize: str | None = None,
                 transfer: Callable | Sequence[float] | None = None):
        if not isinstance(spectrum, Spectrum):
            raise MeshError(f"HeatKernel needs a Spectrum (from o3dheat.eigensolve), got {type(spectrum).__name__}")
        own = variant_of_mass(spectrum.mass_kind)
        if variant is None or (own == "given" and variant == "weighted"):
            variant = own
        elif (need := mass_of(variant)) != spectrum.mass_kind:
            raise MeshError(f"the {variant!r} kernel is the heat kernel of the {need!r} mass, but this spectrum "
                            f"was computed with mass={spectrum.mass_kind!r} (X D_t Xᵀ W with another W does not "
                            f"keep constants): use o3dheat.eigensolve(mesh, k, mass={need!r}) or "
                            f"o3dheat.heat_kernel(mesh, k, variant={variant!r})")
        if not (normalize is None or isinstance(normalize, str)) or normalize not in NORMALIZATIONS:
            raise MeshError(f"unknown normalize {normalize!r}: use one of {', '.join(map(repr, NORMALIZATIONS))}")
        self.spectrum = spectrum
        self.variant = variant
        self.normalize = normalize
        self.transfer = transfer
        lam = np.asarray(spectrum.eigenvalues, dtype=np.float64)
        lam = np.where(_truncation.null_eigenvalues(lam, spectrum.mass), 0.0, lam)  # the constants' 0, exactly
        if normalize == "lambda2":
            lam = lam / first_nonzero(lam)
        phi = transfer_function(transfer)
        self.rates = lam if phi is None else phi(lam)  # φ(λ_i) (normalised): D_t = diag(exp(-rates t / 2))

    def __repr__(self):
        return (f"HeatKernel(variant={self.variant!r}, normalize={self.normalize!r}, "
                f"transfer={'yes' if self.transfer is not None else None}, {self.spectrum!r})")

    # ----------------------------------------------------------------------------------- helpers
    @property
    def n(self) -> int:
        """Number of vertices.

        Examples
        --------
        >>> import open3d as o3d, o3dheat
        >>> o3dheat.heat_kernel(o3d.t.geometry.TriangleMesh.create_sphere(1.0, 8), k=5).n
        114
        """
        return self.spectrum.n

    def _weigh(self, f):
        """W f: the spectrum's mass times f."""
        return self.spectrum.mass @ f

    @cached_property
    def _WX(self):
        """Wᵀ X = W X (W symmetric): rows give the coefficients of the canonic basis."""
        return np.asarray(self._weigh(self.spectrum.eigenvectors))

    _accuracy = cached_property(_truncation.accuracy)  # what the certificates need of the computed eigenpairs

    def _field(self, f, name="f"):
        return checks.field(f, self.n, name)

    def filter_factors(self, t: TimesLike) -> np.ndarray:
        """Filter factors ``exp(-φ(λ_i) t / 2)``.

        Parameters
        ----------
        t : float or (T,) array_like
            Times (>= 0), paper convention.

        Returns
        -------
        (k,) or (k, T) float64 ndarray

        Examples
        --------
        >>> import open3d as o3d, o3dheat
        >>> K = o3dheat.heat_kernel(o3d.t.geometry.TriangleMesh.create_sphere(1.0, 16), k=4)
        >>> K.filter_factors(1.0).round(1).tolist()      # exp(-λ t / 2), λ ≈ 0, 2, 2, 2
        [1.0, 0.4, 0.4, 0.4]
        >>> K.filter_factors([0.5, 1.0]).shape
        (4, 2)
        """
        t_arr = checks.times(t)
        with np.errstate(over="ignore"):
            D = np.exp(-0.5 * np.multiply.outer(self.rates, t_arr))
        if not np.all(np.isfinite(D)):
            raise SolverError(f"the filter factors exp(-φ(λ) t / 2) overflow at t={t}: the transfer function is "
                              "too negative for this time (a negative φ amplifies)")
        return D

    @staticmethod
    def _unit(f):
        """``(f / p, p)`` with ``p`` a power of two bringing ``max |f|`` near 1 when it lies outside
        ``[2^-500, 2^500]`` (exact: no rounding; ``p = 1`` for ordinary fields), so that sums of
        products of huge values do not overflow."""
        m = float(np.max(np.abs(f))) if f.size else 0.0
        if m == 0 or 2.0**-500 <= m <= 2.0**500:
            return f, 1.0
        p = float(2.0 ** np.round(np.log2(m)))
        return f / p, p

    @staticmethod
    def _back(out, p, what):
        """``out * p``, refusing a result that does not fit in float64."""
        with np.errstate(over="ignore", invalid="ignore"):
            out = out * p if p != 1.0 else out
        if not np.all(np.isfinite(out)):
            raise SolverError(f"{what} exceeds the float64 range (|values| > 1.8e308): rescale the field")
        return out

    # ----------------------------------------------------------------------------------- the map
    def coefficients(self, f: FieldLike) -> np.ndarray:
        """Spectral coefficients ``Xᵀ W f`` (for "weighted": ``⟨f, x_i⟩_B``), shape (k,) or (k, c).

        Examples
        --------
        >>> import numpy as np, open3d as o3d, o3dheat
        >>> K = o3dheat.heat_kernel(o3d.t.geometry.TriangleMesh.create_sphere(1.0, 16), k=4)
        >>> c = K.coefficients(np.ones(K.n))      # a constant: only on the constant eigenvector
        >>> bool(np.allclose(c[1:], 0)), bool(c[0] > 0)
        (True, True)
        """
        f, p = self._unit(self._field(f))
        return self._back(self.spectrum.eigenvectors.T @ self._weigh(f), p, "the spectral coefficients")

    def smooth(self, f: FieldLike, t: TimesLike, return_bound: bool = False) -> np.ndarray | tuple[np.ndarray, float | np.ndarray]:
        """Feature map ``Φ_t f = X D_t Xᵀ W f`` (eq. (6), truncated to k eigenpairs).

        Parameters
        ----------
        f : (n,) or (n, c) array_like
            Scalar field(s) per vertex.
        t : float or (T,) array_like
            Time(s) >= 0, paper convention (``exp(-λ t / 2)``). All times are done in one batch.
        return_bound : bool
            Also return the certificate, :meth:`truncation_bound`: how far, at most, the returned
            result is from the full kernel's ``exp(−(t/2) W⁻¹L) f`` (:func:`o3dheat.heat_flow
            <o3dheat.spectral.heatflow.heat_flow>`), in W-norm relative to ``‖f‖_W``: the
            truncation, the computed eigenpairs' accuracy and the rounding (never below ~n u).

        Returns
        -------
        ndarray
            ``(n,)`` or ``(n, c)`` for a scalar ``t``; ``(n, T)`` or ``(n, c, T)`` for an array.
            With ``return_bound``: ``(result, bound)``, the bound a float, ``(T,)``, ``(c,)`` or
            ``(c, T)``.

        Examples
        --------
        >>> import numpy as np, open3d as o3d, o3dheat
        >>> mesh = o3d.t.geometry.TriangleMesh.create_sphere(1.0, 16)
        >>> K = o3dheat.HeatKernel(o3dheat.eigensolve(mesh, k=9))
        >>> g = K.smooth(np.ones(len(mesh.vertex.positions)), 0.3)   # constants are kept
        >>> bool(np.allclose(g, 1.0))
        True
        >>> z = mesh.vertex.positions.numpy()[:, 2] ** 3
        >>> F, bound = K.smooth(z, [0.01, 1.0], return_bound=True)
        >>> bound.round(3).tolist()      # 9 eigenpairs: at t = 0.01 up to 38% off, at t = 1 under 2%
        [0.377, 0.018]
        """
        if return_bound:
            return self.smooth(f, t), self.truncation_bound(f, t)
        f, p = self._unit(self._field(f))
        c = self.coefficients(f)
        D = self.filter_factors(t)
        X = self.spectrum.eigenvectors
        if D.ndim == 1:
            out = X @ (D[:, None] * c if c.ndim == 2 else D * c)
        elif c.ndim == 1:
            out = X @ (D * c[:, None])
        else:
            k, ncol = c.shape
            T = D.shape[1]
            out = (X @ (c[:, :, None] * D[:, None, :]).reshape(k, ncol * T)).reshape(self.n, ncol, T)
        return self._back(out, p, "Φ_t f")

    __call__ = smooth

    def hks(self, t: TimesLike, form: str = HKS_DEFAULT, return_bound: bool = False) -> np.ndarray | tuple[np.ndarray, np.ndarray]:
        """Heat kernel signature at time(s) t.

        Parameters
        ----------
        t : float or (T,) array_like
            Times (>= 0), paper convention.
        form : str
            One of :data:`HKS_FORMS`. "density" (the default everywhere in o3dheat,
            :data:`HKS_DEFAULT`): ``Σ_b e^{-λ_b t/2} x_b(i)²``, the usual HKS of Sun et al. (units
            1/area for the area-weighted variants; stable across samplings).
            "paper": the diagonal of this kernel, ``K_t(i, i) = Σ_b e^{-λ_b t/2} x_b(i) (W x_b)(i)``
            (§2.2): the density times the vertex's own mass row, dimensionless but proportional to
            the local vertex area, so not comparable across samplings (equal to "density" for
            the "linear" kernel, where ``W = I``).

        return_bound : bool
            Also return a bound of how far the result is from the full kernel's, per vertex and
            time, in the units of the HKS: the truncation (``r_k`` the largest rate, ``w_i`` a bound
            of ``Σ_b x_b(i)²`` over a complete basis, :attr:`o3dheat.Spectrum.inverse_mass_bound`)
            ``e^{−r_k t/2} (w_i − Σ_{b<=k} x_b(i)²)``, or for the paper form ``e^{−r_k t/2} sqrt(w_i −
            Σ x_b(i)²) sqrt(W_ii − Σ (W x_b)(i)²)`` (Cauchy–Schwarz), plus the computed eigenpairs'
            accuracy and the rounding (about n u times the HKS: :func:`o3dheat.spectral._truncation.hks_bound`).

        Returns
        -------
        (n,) or (n, T) float64 ndarray
            With ``return_bound``: ``(hks, bound)`` of the same shape.

        Raises
        ------
        MeshError
            ``return_bound`` for a non-diagonal mass built elsewhere, or with a transfer function
            not known to increase (only polynomials with non-negative coefficients are).

        Examples
        --------
        >>> import numpy as np, open3d as o3d, o3dheat
        >>> K = o3dheat.HeatKernel(o3dheat.eigensolve(o3d.t.geometry.TriangleMesh.create_sphere(1.0, 16), k=30))
        >>> h = K.hks(K.scales())
        >>> h.shape[1], bool(np.all(h > 0))
        (10, True)
        >>> h, bound = K.hks([0.05, 0.5], return_bound=True)
        >>> (bound / h).max(axis=0).round(2).tolist()   # 30 eigenpairs: no digit at t = 0.05
        [117.6, 0.39]
        """
        if form not in HKS_FORMS:
            raise MeshError(f"unknown HKS form {form!r}: use one of {', '.join(HKS_FORMS)}")
        D = self.filter_factors(t)
        X = self.spectrum.eigenvectors
        P = X * (self._WX if form == "paper" else X)
        h = P @ D
        if not return_bound:
            return h
        return h, _truncation.hks_bound(self, t, form, self._WX)

    #: Wave kernel signature on this kernel's rates and eigenvectors: :func:`o3dheat.spectral.signatures.wks`.
    wks = signatures.wks
    #: Scale-invariant HKS of this kernel: :func:`o3dheat.spectral.signatures.si_hks`.
    si_hks = signatures.si_hks

    def scales(self, count: int = 10, grid: str = "paper") -> np.ndarray:
        """Times for a scale sweep, ``count`` of them, increasing.

        * ``grid="paper"``: the paper's ``t_i = (i / count) / λ_k``, ``i = 1..count`` (§2.3). With
          many eigenpairs these times all lie where only the highest modes are damped: Φ_t f barely
          changes across them (it is already the band-limited ``X Xᵀ W f`` at ``t ≈ 0``).
        * ``grid="log"``: log-spaced from ``1 / λ_k`` (the highest mode kept at ``e^{-1/2}``) to
          ``2 ln(100) / λ_2`` (the first non-constant mode damped to 1%, Φ_t f nearly constant):
          the whole multi-scale range, from what k eigenpairs resolve to the global mean.

        ``λ_k`` is the largest and ``λ_2`` the first non-zero rate (normalised, transferred) of
        this kernel.

        Parameters
        ----------
        count : int
            Number of times (1 to 100000).
        grid : str
            One of :data:`GRIDS`.

        Returns
        -------
        (count,) float64 ndarray

        Examples
        --------
        >>> import open3d as o3d, o3dheat
        >>> K = o3dheat.HeatKernel(o3dheat.eigensolve(o3d.t.geometry.TriangleMesh.create_sphere(1.0, 16), k=36))
        >>> K.spectrum.eigenvalues[[1, -1]].round(2).tolist()   # λ_2 and λ_k
        [2.02, 33.29]
        >>> K.scales(3).round(4).tolist()                       # (i/3) / λ_k
        [0.01, 0.02, 0.03]
        >>> K.scales(3, grid="log").round(4).tolist()           # 1/λ_k .. 2 ln(100)/λ_2
        [0.03, 0.3703, 4.5656]
        """
        count = checks.count(count, "count", maximum=100_000)
        if grid not in GRIDS:
            raise MeshError(f"unknown scale grid {grid!r}: use one of {', '.join(GRIDS)}")
        lk = float(np.max(self.rates))
        if lk <= 0 or all_zero(self.spectrum.eigenvalues, self.spectrum.mass):
            raise MeshError(f"all {len(self.rates)} eigenvalues are zero (a mesh with at least as many connected "
                            "components as eigenpairs has only constant eigenfunctions): compute more "
                            "eigenpairs than the mesh has components to define the scales")
        if grid == "paper":
            return np.arange(1, count + 1) / count / lk
        lo, hi = 1.0 / lk, 2.0 * np.log(100.0) / first_nonzero(self.rates)
        if hi <= lo:  # few eigenpairs: λ_k close to λ_2
            hi = 10.0 * lo
        return np.geomspace(lo, hi, count) if count > 1 else np.array([lo])

    def error(self, f: FieldLike, t: TimesLike) -> float | np.ndarray:
        """Relative approximation error ``ε∞ = ‖f − Φ_t f‖∞ / ‖f‖∞`` (0 when f = 0).

        Parameters
        ----------
        f : (n,) array_like
            The field, one value per vertex.
        t : float or (T,) array_like
            Time(s) (paper convention, >= 0): one error per time.

        Returns
        -------
        float or (T,) ndarray

        Examples
        --------
        >>> import open3d as o3d, o3dheat
        >>> mesh = o3d.t.geometry.TriangleMesh.create_sphere(1.0, 16)
        >>> K = o3dheat.heat_kernel(mesh, k=20)
        >>> K.error(mesh.vertex.positions.numpy()[:, 2], [0.01, 1.0]).round(2).tolist()  # grows with t
        [0.01, 0.63]
        """
        f = self._field(f)
        if f.ndim != 1:
            raise MeshError("error() takes one scalar field (n,)")
        f = self._unit(f)[0]  # ε∞ is scale free
        F = self.smooth(f, t)
        nf = np.abs(f).max()
        d = np.abs(F - (f[:, None] if F.ndim == 2 else f)).max(axis=0)
        return d / nf if nf > 0 else d * 0.0

    # ----------------------------------------------------------------------- basis and inverse
    def canonic_basis(self, i: int | Sequence[int], t: float) -> np.ndarray:
        """Canonic basis function(s) ``Φ_t(e_i) = X D_t Xᵀ W e_i`` (§3.2).

        Parameters
        ----------
        i : int or sequence of int
            Vertex index (indices).
        t : float
            Time (>= 0).

        Returns
        -------
        (n,) or (n, len(i)) float64 ndarray

        Examples
        --------
        >>> import open3d as o3d, o3dheat
        >>> K = o3dheat.heat_kernel(o3d.t.geometry.TriangleMesh.create_sphere(1.0, 16), k=20)
        >>> K.canonic_basis(0, 0.1).shape, K.canonic_basis([0, 5], 0.1).shape
        ((482,), (482, 2))
        """
        idx = np.asarray(i)
        if not np.issubdtype(idx.dtype, np.integer) or idx.ndim > 1:
            raise MeshError(f"i must be a vertex index or a 1-D sequence of them, got {i!r}")
        if np.any(idx < 0) or np.any(idx >= self.n):
            raise MeshError(f"vertex index out of range [0, {self.n - 1}]: {i!r}")
        t = checks.times(t)
        if t.ndim:
            raise MeshError("canonic_basis takes one time t")
        D = self.filter_factors(t)
        coef = self._WX[idx].T  # (k,) or (k, c)
        return self.spectrum.eigenvectors @ (D[:, None] * coef if coef.ndim == 2 else D * coef)

    def inverse(self, f: FieldLike, t: float) -> np.ndarray:
        """Inverse feature map ``Φ_t^{-1}`` on the spectral span (§3.2): ``α`` with ``Φ_t α = P f``.

        ``P`` is the ``W``-orthogonal projection onto the span of the k eigenvectors, and
        ``α = X D_t^{-1} Xᵀ W f`` (for the linear kernel, ``W = I``: the paper's linear-time
        formula). ``inverse(smooth(f, t), t) = P f``, and both are exact when the spectrum is
        complete (k = n).

        Parameters
        ----------
        f : (n,) or (n, c) array_like
            The field(s), one row per vertex.
        t : float
            Time (>= 0). Large ``λ_k t`` makes the inverse ill-conditioned (``exp(λ_k t / 2)``).

        Returns
        -------
        ndarray of the shape of f

        Raises
        ------
        SolverError
            When ``exp(λ_k t / 2)`` overflows or exceeds 1e15 (no digit would be right).

        Examples
        --------
        >>> import numpy as np, open3d as o3d, o3dheat
        >>> mesh = o3d.t.geometry.TriangleMesh.create_sphere(1.0, 16)
        >>> K = o3dheat.heat_kernel(mesh, k=20)
        >>> f = mesh.vertex.positions.numpy()[:, 2]
        >>> Pf = K.smooth(f, 0.0)                 # the projection on the k eigenvectors
        >>> bool(np.allclose(K.inverse(K.smooth(f, 0.1), 0.1), Pf))
        True
        """
        f = self._field(f)
        t = checks.times(t)
        if t.ndim:
            raise MeshError("inverse takes one time t")
        expo = 0.5 * float(np.max(self.rates)) * float(t)
        if expo > np.log(1e15):
            raise SolverError(f"the inverse at t={float(t):g} amplifies by exp({expo:.3g}) > 1e15: use a "
                              "smaller t or fewer eigenpairs")
        f, p = self._unit(f)
        g = self.coefficients(f)  # coordinates of P f
        Dinv = np.exp(0.5 * self.rates * float(t))
        return self._back(self.spectrum.eigenvectors @ (Dinv[:, None] * g if g.ndim == 2 else Dinv * g), p,
                          "the inverse")

    # ------------------------------------------------------------------ truncation (o3dheat.spectral._truncation)
    truncation_bound = _truncation.truncation_bound
    suggest_k = _truncation.suggest_k
