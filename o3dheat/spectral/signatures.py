"""The descriptors compared with the heat kernel signature: :func:`wks` (wave kernel signature) and
:func:`si_hks` (scale-invariant HKS), on a :class:`~o3dheat.spectral.kernel.HeatKernel`'s own
spectrum and mass (also its methods :meth:`HeatKernel.wks <o3dheat.spectral.kernel.HeatKernel.wks>`
and :meth:`HeatKernel.si_hks <o3dheat.spectral.kernel.HeatKernel.si_hks>`).

Notes
-----
Both use the kernel's rates (its eigenvalues ``λ_i`` of ``L x = λ W x``, normalised and transferred
as the kernel says) and its W-orthonormal eigenvectors, whose squares ``x_i(v)²`` are densities
(1/area), as in the "density" HKS.

**WKS** (Aubry, Schlickewei & Cremers, ICCV Workshops 2011): for log-energies ``e``,
``WKS(v, e) = Σ_i x_i(v)² g_i(e) / Σ_i g_i(e)`` with ``g_i(e) = exp(−(e − log λ_i)² / (2σ²))``, over
the non-zero eigenvalues. By default ``energies`` log-energies evenly spaced from ``log λ_2`` to
``log λ_k / 1.02`` and ``σ`` = 6 times their spacing (Aubry's choices in their code). Truncation to
the k smallest eigenpairs drops the terms ``λ_i > λ_k``; each has ``g_i(e) <= g_k(e) :=
exp(−(e − log λ_k)² / (2σ²))`` for ``e <= log λ_k``, so with ``w_v`` a bound of ``Σ_i x_i(v)²`` over the
complete basis (:attr:`o3dheat.Spectrum.inverse_mass_bound`), ``C_k(e) = Σ_{i<=k} g_i(e)`` and
``N`` the number of vertices, the full WKS lies within ``g_k(e) · max(w_v − Σ_{i<=k} x_i(v)²,
WKS_k(v, e) · (N − k)) / C_k(e)`` of the truncated one (``return_bound=True``). The bound is small
only for energies a few ``σ`` below ``log λ_k``: that is what Aubry's margin is for.

**SI-HKS** (Bronstein & Kokkinos, CVPR 2010): the density HKS ``h(v, t)`` sampled at ``t = α^τ`` on
a fixed grid of ``τ``, its logarithm, the discrete derivative in ``τ`` and the magnitudes of the
discrete Fourier transform of that, of which the first ``frequencies`` are kept. Scaling a surface
by ``a`` multiplies its eigenvalues by ``a⁻²`` and its densities by ``a⁻²``, so ``log h`` gains a
constant (removed by the derivative) and is shifted in ``τ`` by ``2 log_α a`` (removed by the
magnitude of the Fourier transform, as long as the derivative vanishes at both ends of the grid:
it does, since the truncated HKS is flat below ``1/λ_k`` and above a few ``1/λ_2``). The default grid
``τ ∈ [−40, 40]`` (``t`` from 1e-12 to 1e12, 321 times) covers surfaces of size 1e-4 to 1e4 with
100 eigenpairs, and the dimensionless "linear" kernel; :func:`si_hks` refuses (naming the grid to
use) when the derivative does not vanish at the ends.
The paper's normalisation (``normalize="lambda2"``: rates ``λ / λ_2``) gives the same invariance
exactly, without the loss of the time information the Fourier magnitude discards.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from o3dheat import checks
from o3dheat.errors import MeshError

from .spectrum import inverse_mass_bound

if TYPE_CHECKING:
    from .kernel import HeatKernel

__all__ = ["wks", "si_hks", "wks_energies", "WKS_VARIANCE", "SI_HKS_GRID"]

#: Aubry's default width of the WKS filters, in units of the spacing of the energies
WKS_VARIANCE = 6.0
#: SI-HKS default grid: (alpha, tau from, tau to, tau step)
SI_HKS_GRID = (2.0, -40.0, 40.0, 0.25)


def _nonzero(kernel):
    """(rates, X) of the kernel's non-zero rates (those above 1e-9 of the largest)."""
    r = np.asarray(kernel.rates, dtype=np.float64)
    keep = r > 1e-9 * max(float(r.max()), 1e-300)
    if keep.sum() < 2:
        raise MeshError(f"the WKS needs at least 2 non-zero eigenvalues, this kernel has {int(keep.sum())}: compute "
                        "more eigenpairs than the mesh has connected parts")
    return r[keep], kernel.spectrum.eigenvectors[:, keep]


def wks_energies(kernel: HeatKernel, count: int = 100) -> tuple[np.ndarray, float]:
    """Aubry's log-energies and filter width for a kernel: ``count`` energies evenly spaced from
    ``log λ_2`` to ``log λ_k / 1.02`` and ``σ = WKS_VARIANCE`` times their spacing.

    Parameters
    ----------
    kernel : HeatKernel
        Its rates (non-zero ones) define the range.
    count : int
        Number of energies (at least 2).

    Returns
    -------
    energies : (count,) float64 ndarray
    sigma : float

    Examples
    --------
    >>> import open3d as o3d, o3dheat
    >>> from o3dheat.spectral.signatures import wks_energies
    >>> K = o3dheat.heat_kernel(o3d.t.geometry.TriangleMesh.create_sphere(1.0, 16), k=30)
    >>> e, sigma = wks_energies(K, 5)
    >>> e.round(2).tolist(), round(sigma, 2)
    ([0.7, 1.38, 2.07, 2.75, 3.43], 4.1)
    """
    count = checks.count(count, "energies", minimum=2, maximum=100_000)
    r, _ = _nonzero(kernel)
    lo, hi = float(np.log(r.min())), float(np.log(r.max())) / 1.02
    if not hi > lo:
        hi = float(np.log(r.max()))
    if not hi > lo:
        raise MeshError("the WKS needs distinct non-zero eigenvalues: all are equal here")
    e = np.linspace(lo, hi, count)
    return e, WKS_VARIANCE * float(e[1] - e[0])


def wks(kernel: HeatKernel, energies: int | np.ndarray = 100, sigma: float | None = None,
        return_bound: bool = False) -> np.ndarray | tuple[np.ndarray, np.ndarray]:
    """The wave kernel signature on the kernel's spectrum (see the module Notes).

    Parameters
    ----------
    kernel : HeatKernel
        Its rates and W-orthonormal eigenvectors.
    energies : int or (E,) array_like
        That many of Aubry's log-energies (:func:`wks_energies`), or the log-energies themselves
        (finite; they must lie within the spectrum, ``log λ_2 .. log λ_k``).
    sigma : float, optional
        Width of the filters in log-energy (> 0); default Aubry's: ``WKS_VARIANCE`` times the spacing
        of the default energies (of ``len(energies)`` of them).
    return_bound : bool
        Also return the truncation bound per vertex and energy (the module Notes).

    Returns
    -------
    (n, E) float64 ndarray
        With ``return_bound``: ``(wks, bound)`` of the same shape.

    Examples
    --------
    >>> import numpy as np, open3d as o3d, o3dheat
    >>> K = o3dheat.heat_kernel(o3d.t.geometry.TriangleMesh.create_sphere(1.0, 16), k=30)
    >>> W = K.wks(8)
    >>> W.shape, bool(np.all(W > 0))
    ((482, 8), True)
    """
    r, X = _nonzero(kernel)
    if isinstance(energies, (int, np.integer)) and not isinstance(energies, bool):
        e, default_sigma = wks_energies(kernel, int(energies))
    else:
        e = np.asarray(checks.values(energies), dtype=np.float64).reshape(-1)
        if e.size == 0 or not np.all(np.isfinite(e)):
            raise MeshError("energies must be a count or finite log-energies")
        lo, hi = float(np.log(r.min())), float(np.log(r.max()))
        if e.min() < lo - 1e-12 or e.max() > hi + 1e-12:
            raise MeshError(f"log-energies must lie within the spectrum, log λ in [{lo:.4g}, {hi:.4g}] "
                            f"(λ_2 .. λ_k of this kernel), got [{e.min():.4g}, {e.max():.4g}]")
        default_sigma = WKS_VARIANCE * (hi / 1.02 - lo) / max(len(e) - 1, 1)
    if sigma is None:
        sigma = default_sigma
    if isinstance(sigma, bool) or not isinstance(sigma, (int, float, np.integer, np.floating)) or \
            not (np.isfinite(sigma) and sigma > 0):
        raise MeshError(f"sigma must be a positive number (a width in log-energy), got {sigma!r}")
    G = np.exp(-np.subtract.outer(e, np.log(r)) ** 2 / (2.0 * sigma**2))  # (E, k)
    C = G.sum(axis=1)
    if np.any(C <= 0):
        raise MeshError(f"sigma={sigma:.3g} is too narrow for these energies: no eigenvalue is near some of them")
    out = (X * X) @ (G / C[:, None]).T
    if not return_bound:
        return out
    w = kernel.spectrum.inverse_mass_bound
    if w is None:
        w = inverse_mass_bound(kernel.spectrum.mass, kernel.spectrum.mass_kind)
    if w is None:
        raise MeshError("no truncation bound for this spectrum: its mass is not diagonal nor the consistent FEM mass")
    top = float(np.log(r.max()))
    g_k = np.where(e <= top, np.exp(-(e - top) ** 2 / (2.0 * sigma**2)), 1.0)  # (E,): every dropped g_i(e) <= it
    dropped = max(kernel.n - kernel.spectrum.k, 0)
    tail = np.maximum(np.asarray(w) - np.einsum("ij,ij->i", kernel.spectrum.eigenvectors,
                                                kernel.spectrum.eigenvectors), 0.0)
    bound = (g_k / C)[None, :] * np.maximum(tail[:, None], out * dropped)
    return out, bound if dropped else np.zeros_like(out)


def si_hks(kernel: HeatKernel, frequencies: int = 8, grid: tuple[float, float, float, float] = SI_HKS_GRID) -> np.ndarray:
    """The scale-invariant heat kernel signature (see the module Notes).

    Parameters
    ----------
    kernel : HeatKernel
        Its density HKS ``Σ_i e^{−λ_i t/2} x_i(v)²`` is sampled.
    frequencies : int
        How many of the lowest frequencies of the Fourier magnitude are kept (from the constant one).
    grid : (alpha, tau_from, tau_to, tau_step)
        ``t = alpha ** tau`` for ``tau`` from ``tau_from`` to ``tau_to`` by ``tau_step`` (default
        :data:`SI_HKS_GRID`: 1e-12 .. 1e12, 321 times). Fixed, not taken from the spectrum: the
        invariance comes from the Fourier magnitude, not from a normalisation.

    Returns
    -------
    (n, frequencies) float64 ndarray

    Raises
    ------
    MeshError
        Bad arguments, or a grid whose ends do not contain this surface's scale space (the HKS
        still changes there: a surface far larger or smaller than the grid assumes), naming the
        grid to use.

    Examples
    --------
    >>> import numpy as np, open3d as o3d, o3dheat
    >>> m = o3d.t.geometry.TriangleMesh.create_sphere(1.0, 16)
    >>> big = o3d.t.geometry.TriangleMesh.create_sphere(2.0, 16)
    >>> a = o3dheat.heat_kernel(m, k=30).si_hks()
    >>> b = o3dheat.heat_kernel(big, k=30).si_hks()      # the same sphere, twice the size
    >>> a.shape, bool(np.abs(a - b).max() < 1e-3 * np.abs(a).max())
    ((482, 8), True)
    """
    try:
        alpha, lo, hi, step = (float(x) for x in grid)
    except (TypeError, ValueError):
        raise MeshError(f"grid must be (alpha, tau_from, tau_to, tau_step), got {grid!r}") from None
    if not (np.isfinite([alpha, lo, hi, step]).all() and alpha > 1 and step > 0 and hi > lo + 4 * step):
        raise MeshError(f"grid needs alpha > 1, tau_step > 0 and at least 5 steps from tau_from to tau_to, got {grid!r}")
    taus = lo + step * np.arange(int(np.floor((hi - lo) / step + 1e-9)) + 1)
    F = checks.count(frequencies, "frequencies", maximum=len(taus) - 1)
    t = alpha**taus
    X = kernel.spectrum.eigenvectors
    r = np.asarray(kernel.rates, dtype=np.float64)
    r = np.where(r > 1e-9 * max(float(r.max()), 1e-300), r, 0.0)  # the constants' rates: 0, not their rounding
    # log h = log Σ_i x_i² e^{−r_i t/2}, as a log-sum-exp: no underflow at the large times of the grid
    with np.errstate(divide="ignore"):
        logx2 = np.log(X * X)  # (n, k); −inf where an eigenvector vanishes
    logh = np.empty((len(X), len(t)))
    for j, tj in enumerate(t):
        a = logx2 - 0.5 * r * tj
        top = a.max(axis=1)
        if not np.all(np.isfinite(top)):
            raise MeshError("the HKS vanishes at some vertex (in no eigenvector's support): its logarithm is undefined")
        logh[:, j] = top + np.log(np.exp(a - top[:, None]).sum(axis=1))
    d = np.diff(logh, axis=1)
    scale = float(np.abs(d).max()) or 1.0
    ends = max(float(np.abs(d[:, :2]).max()), float(np.abs(d[:, -2:]).max())) / scale
    if ends > 1e-3:
        r = r[r > 0]
        need = (np.floor(np.log(0.01 / r.max()) / np.log(alpha)), np.ceil(np.log(50.0 / r.min()) / np.log(alpha)))
        raise MeshError(f"the SI-HKS grid t = {alpha:g}^tau, tau in [{lo:g}, {hi:g}] does not contain this surface's "
                        f"scale space (the HKS still changes at its ends: {ends:.1e} of its largest change); use "
                        f"grid=({alpha:g}, {min(lo, need[0]):g}, {max(hi, need[1]):g}, {step:g})")
    return np.abs(np.fft.fft(d, axis=1))[:, :F]
