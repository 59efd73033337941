"""The truncation bounds of :class:`o3dheat.HeatKernel <o3dheat.spectral.kernel.HeatKernel>`: what the eigenpairs above ``λ_k`` would add.

Entry points: :func:`truncation_bound` and :func:`suggest_k` (methods of
:class:`~o3dheat.spectral.kernel.HeatKernel`, defined here and bound there), :func:`hks_bound` (the bound of
:meth:`~o3dheat.spectral.kernel.HeatKernel.hks`), :func:`top_rate`.
"""

from __future__ import annotations

import numpy as np

from o3dheat import checks
from o3dheat.errors import MeshError, SolverError
from o3dheat.typing import FieldLike, TimesLike

from .spectrum import inverse_mass_bound
from .variants import transfer_function


def top_rate(kernel):
    """The largest rate φ(λ_k) of a :class:`~o3dheat.spectral.kernel.HeatKernel`, a lower bound of every dropped
    rate when φ increases (refused for a transfer function not known to increase)."""
    phi = transfer_function(kernel.transfer)
    if phi is not None and (phi.coefficients is None or np.any(phi.coefficients < 0)):
        raise MeshError("the truncation bound needs a transfer function that increases: polynomial "
                        "coefficients >= 0 (a callable or a negative coefficient cannot be certified)")
    return float(np.max(kernel.rates))


def hks_bound(kernel, t, form, WX):
    """The bound of ``kernel.hks(t, form, return_bound=True)`` per vertex and time (``WX``: the
    mass times the eigenvectors, for the paper form)."""
    X = kernel.spectrum.eigenvectors
    w = kernel.spectrum.inverse_mass_bound
    if w is None:  # a Spectrum made by hand: bounded from its mass where that is possible
        w = inverse_mass_bound(kernel.spectrum.mass, kernel.spectrum.mass_kind)
    if w is None:
        raise MeshError("no truncation bound for this spectrum: its mass is not diagonal nor the consistent "
                        "FEM mass (the diagonal of its inverse is not bounded)")
    decay = np.exp(-0.5 * top_rate(kernel) * checks.times(t))
    tail_x = np.maximum(w - np.einsum("ij,ij->i", X, X), 0.0)
    if form == "density":
        tail = tail_x
    else:
        tail_w = np.maximum(kernel.spectrum.mass.diagonal() - np.einsum("ij,ij->i", WX, WX), 0.0)
        tail = np.sqrt(tail_x * tail_w)
    with np.errstate(invalid="ignore"):  # an unbounded tail (a vertex of zero mass) times exp(-inf)
        bound = np.multiply.outer(tail, decay)
    return np.where(np.isnan(bound), 0.0, bound)


def truncation_bound(self, f: FieldLike, t: TimesLike) -> float | np.ndarray:  # noqa: D417 - HeatKernel's method
    """Upper bound of what dropping the eigenpairs above ``λ_k`` costs at time t.

    With ``P`` the W-orthogonal projection on the k eigenvectors (``W`` the spectrum's mass),
    the full-spectrum map satisfies ``‖Φ_t f − Φ_t^{(k)} f‖_W <= exp(−φ(λ_k) t / 2) ‖f − P f‖_W``
    (every dropped eigenvalue is >= λ_k and φ increasing). Returned relative to ``‖f‖_W``.
    A rigorous bound for every variant (refused for a transfer function not known to increase:
    only polynomials with non-negative coefficients are).

    Parameters
    ----------
    f : (n,) array_like
        The field, one value per vertex.
    t : float or (T,) array_like
        Time(s) (paper convention, >= 0): one bound per time.

    Returns
    -------
    float or (T,) ndarray

    Examples
    --------
    >>> import open3d as o3d, o3dheat
    >>> mesh = o3d.t.geometry.TriangleMesh.create_sphere(1.0, 16)
    >>> K = o3dheat.heat_kernel(mesh, k=20)
    >>> b = K.truncation_bound(mesh.vertex.positions.numpy()[:, 0] ** 2, [0.0, 0.1])
    >>> bool(b[1] < b[0] < 0.01)              # x² is nearly in the span of 20 eigenvectors
    True
    """
    f = self._field(f)
    B = self.spectrum.mass
    X = self.spectrum.eigenvectors
    r = f - X @ (X.T @ (B @ f))
    nr = np.sqrt(max(float(r @ (B @ r)), 0.0)) if f.ndim == 1 else np.sqrt(np.einsum("ij,ij->j", r, B @ r))
    nf = np.sqrt(float(f @ (B @ f))) if f.ndim == 1 else np.sqrt(np.einsum("ij,ij->j", f, B @ f))
    decay = np.exp(-0.5 * top_rate(self) * checks.times(t))
    with np.errstate(invalid="ignore", divide="ignore"):
        rel = np.where(nf > 0, nr / np.where(nf > 0, nf, 1), 0.0)
    return np.multiply.outer(rel, decay) if np.ndim(rel) else float(rel) * decay


def suggest_k(self, t: float, tol: float = 1e-3) -> int:  # noqa: D417 - HeatKernel's method
    """Estimate how many eigenpairs make the truncation factor ``exp(−φ(λ_k) t/2)`` <= tol.

    Uses Weyl's law (``λ_j`` grows linearly with ``j`` on a surface), with the slope fitted to
    this spectrum's upper half of eigenvalues. An estimate, not a guarantee.

    Parameters
    ----------
    t : float
        Time (> 0).
    tol : float
        Target factor, in (0, 1).

    Returns
    -------
    int

    Examples
    --------
    >>> import open3d as o3d, o3dheat
    >>> K = o3dheat.heat_kernel(o3d.t.geometry.TriangleMesh.create_sphere(1.0, 16), k=20)
    >>> K.suggest_k(0.1) < K.suggest_k(0.01)  # small times need more eigenpairs
    True
    """
    t = float(checks.times(t))
    if t <= 0 or not (0 < tol < 1):
        raise MeshError("suggest_k needs t > 0 and 0 < tol < 1")
    need = 2 * np.log(1 / tol) / t  # the rate λ_k must reach
    k = len(self.rates)
    j = np.arange(1, k + 1)
    half = slice(k // 2, k)
    slope = float(np.sum(self.rates[half] * j[half]) / np.sum(j[half] ** 2))
    if slope <= 0:
        raise SolverError("cannot extrapolate from an all-zero spectrum")
    return int(np.ceil(need / slope))
