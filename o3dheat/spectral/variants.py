"""The kernel variants, scale grids, HKS forms and normalisations, defined here once for the package.

Entry points: :data:`VARIANTS`, :data:`GRIDS`, :data:`HKS_FORMS`, :data:`HKS_DEFAULT`,
:data:`NORMALIZATIONS`, :func:`mass_of`, :func:`variant_of_mass`, :func:`first_nonzero`,
:func:`transfer_function`. Every consumer reads them here (a variant added to :data:`VARIANTS` here
reaches the kernels, the filters, the command and the studies: this file is the only one to edit).

Notes
-----
Each kernel variant is the heat kernel of its own eigenproblem ``L x = λ W x`` (its spectrum's
mass ``W``, eigenvectors ``W``-orthonormal): ``K_t = X D_t Xᵀ W``. So every variant keeps
constants (``K_t 1 = 1``), conserves the total ``1ᵀ W f``, is a semigroup
(``K_s K_t = K_{s+t}``) and tends to the ``W``-weighted mean as ``t → ∞``. The variants:

* "weighted" — the paper's weighted linear FEM kernel (§2.1): ``W = B``, the consistent FEM mass;
* "linear" — the paper's linear FEM kernel, "B := I" (§2.1): eigenpairs of ``L x = λ x``,
  ``K_t = X D_t Xᵀ``;
* "voronoi" — eq. (7) (§2.3) as Sun et al. compute it: eigenpairs of ``L x = λ A x`` with
  ``A = diag(a)`` the mixed Voronoi areas of Meyer et al., and ``K_t = X D_t Xᵀ A``;
* "lumped" — common practice: ``W = diag(row sums of B)``, the barycentric lumped mass.

A kernel is built on a spectrum computed with its mass (:func:`o3dheat.spectral.kernel.heat_kernel`
does both steps); pairing a variant with another spectrum is refused, since ``X D_t Xᵀ W`` with
``W`` other than the spectrum's mass is not a heat kernel (it does not even keep constants).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np
from numpy.typing import ArrayLike

from o3dheat.errors import MeshError

__all__ = ["VARIANTS", "GRIDS", "HKS_FORMS", "HKS_DEFAULT", "NORMALIZATIONS", "mass_of", "variant_of_mass",
           "first_nonzero", "transfer_function"]

#: kernel variant -> (mass of its eigenproblem, a key of :data:`o3dheat.spectral.fem.MASS_KINDS`; what it is
#: in one line). The one definition used by the filters, the command, the studies and the figures:
#: a variant added here is reachable from the ``hks``, ``heat_smooth`` and ``feature_approx``
#: filters, ``o3dheat apply`` and ``o3dheat study`` without other edits (a new mass kind is added to
#: :mod:`o3dheat.spectral.fem`).
VARIANTS = {
    "weighted": ("consistent", "the paper's kernel X D_t Xᵀ B, B the consistent FEM mass (§2.1)"),
    "linear": ("identity", "the paper's B := I kernel X D_t Xᵀ, eigenpairs of L x = λ x (§2.1)"),
    "voronoi": ("voronoi", "eq. (7): X D_t Xᵀ A, eigenpairs of L x = λ A x, A = Voronoi areas (§2.3)"),
    "lumped": ("lumped", "X D_t Xᵀ D, eigenpairs of L x = λ D x, D = lumped (row-sum) mass"),
}
#: scale grids of :meth:`o3dheat.HeatKernel.scales <o3dheat.spectral.kernel.HeatKernel.scales>`
GRIDS = ("paper", "log")
#: heat kernel signature forms of :meth:`o3dheat.HeatKernel.hks <o3dheat.spectral.kernel.HeatKernel.hks>`; the default everywhere is "density"
HKS_FORMS = ("density", "paper")
HKS_DEFAULT = "density"
#: eigenvalue normalisations of :class:`o3dheat.HeatKernel <o3dheat.spectral.kernel.HeatKernel>` (``normalize=``): None, or "lambda2" (divided by
#: the first non-zero eigenvalue: the scale-invariant kernel, §2.2)
NORMALIZATIONS = (None, "lambda2")


def first_nonzero(eigenvalues: ArrayLike) -> float:
    """The first non-zero of ascending eigenvalues (above 1e-8 of the largest): ``λ_2`` of a
    connected mesh, the divisor of ``normalize="lambda2"``.

    Raises
    ------
    MeshError
        Every eigenvalue is zero (only constants per component).

    Examples
    --------
    >>> from o3dheat.spectral.variants import first_nonzero
    >>> first_nonzero([1e-15, 2.0, 6.0])
    2.0
    """
    lam = np.asarray(eigenvalues, dtype=np.float64)
    tol = 1e-8 * max(float(np.max(np.abs(lam))), 1e-300)
    nz = lam[lam > tol]
    if nz.size == 0:
        raise MeshError("normalize='lambda2' needs a non-zero eigenvalue: compute more eigenpairs")
    return float(nz[0])


def transfer_function(transfer: Callable | Sequence[float] | None) -> Callable | None:
    """The transfer function φ of ``transfer`` (§2.3) as a checked, vectorised callable; None for None.

    Parameters
    ----------
    transfer : None, callable or sequence of float
        A vectorised callable ``φ(λ)``, or polynomial coefficients in increasing degree
        ``c0 + c1 λ + c2 λ² ...``.

    Returns
    -------
    callable or None
        ``λ (k,) -> φ(λ) (k,)``, raising :class:`~o3dheat.errors.MeshError` when φ does not map the
        eigenvalues to as many finite values.

    Examples
    --------
    >>> from o3dheat.spectral.variants import transfer_function
    >>> transfer_function([0.0, 1.0, 0.5])([0.0, 2.0]).tolist()      # λ + λ²/2
    [0.0, 4.0]
    """
    if transfer is None:
        return None
    if callable(transfer):
        fn = transfer
    else:
        try:
            coef = np.asarray(transfer, dtype=np.float64)
        except (TypeError, ValueError):
            coef = np.zeros((0, 0))
        if coef.ndim != 1 or coef.size == 0 or not np.all(np.isfinite(coef)):
            raise MeshError("transfer must be a callable or a 1-D sequence of finite polynomial coefficients")

        def fn(lam):
            return np.polynomial.polynomial.polyval(lam, coef)

        fn.coefficients = coef

    def phi(lam):
        lam = np.asarray(lam, dtype=np.float64)
        try:
            out = np.asarray(fn(lam), dtype=np.float64)
        except (TypeError, ValueError) as e:
            raise MeshError(f"the transfer function failed on the eigenvalues ({type(e).__name__}: {e})") from e
        if out.shape != lam.shape or not np.all(np.isfinite(out)):
            raise MeshError("the transfer function must map the eigenvalues to as many finite values")
        return out

    phi.coefficients = getattr(fn, "coefficients", None)
    return phi


def _unknown_variant(variant):
    return MeshError(f"unknown kernel variant {variant!r}: use one of {', '.join(VARIANTS)}")


def mass_of(variant: str) -> str:
    """The mass kind of a kernel variant's eigenproblem (:data:`VARIANTS`).

    Parameters
    ----------
    variant : str
        A key of :data:`VARIANTS`.

    Returns
    -------
    str
        A key of :data:`o3dheat.spectral.fem.MASS_KINDS`.

    Raises
    ------
    MeshError
        An unknown variant (the message lists them).

    Examples
    --------
    >>> from o3dheat.spectral.variants import mass_of
    >>> mass_of("weighted"), mass_of("linear")
    ('consistent', 'identity')
    """
    if not isinstance(variant, str) or variant not in VARIANTS:
        raise _unknown_variant(variant)
    return VARIANTS[variant][0]


def variant_of_mass(mass_kind: str) -> str:
    """The variant whose eigenproblem uses ``mass_kind`` (the first in :data:`VARIANTS`; "given"
    for operators built elsewhere, :func:`o3dheat.spectral.spectrum.eigensolve_operators`).

    Examples
    --------
    >>> from o3dheat.spectral.variants import variant_of_mass
    >>> variant_of_mass("voronoi"), variant_of_mass("given")
    ('voronoi', 'given')
    """
    for name, (mass, _) in VARIANTS.items():
        if mass == mass_kind:
            return name
    return "given"
