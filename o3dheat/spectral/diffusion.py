"""Time stepping of the heat equation ``B ∂_t F = −L F / 2`` (paper §2.3): :func:`diffuse`.

Entry points: :func:`diffuse`, :func:`explicit_step_limit`, :data:`SCHEMES`: the explicit scheme of
eq. (8), ``B F(t+dt) = (B − dt L / 2) F(t)``, and backward (implicit) Euler,
``(B + dt L / 2) F(t+dt) = B F(t)``. Either way one matrix is factorized once for all steps, and
many fields are stepped at once.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from o3dheat import checks
from o3dheat.errors import MeshError, SolverError
from o3dheat.geometry import prepare
from o3dheat.typing import FieldLike, MeshLike

from . import fem
from .linalg import factorize

__all__ = ["diffuse", "explicit_step_limit", "SCHEMES"]

#: time-stepping schemes of :func:`diffuse`: eq. (8) and backward Euler
SCHEMES = ("explicit", "implicit")


def _largest_rate(L, B, backend="auto"):
    """``λ_max`` of ``L x = λ B x`` (the largest rate of ``B⁻¹L``), to about 1e-10 relative: a dense
    solve up to 200 vertices, Lanczos (ARPACK, deterministic start) above; ``B`` scaled to a mean
    diagonal of 1 first (the rates of a mesh scaled by α are α⁻² times its own, over any α)."""
    import scipy.linalg
    from scipy.sparse.linalg import ArpackNoConvergence, LinearOperator, eigsh

    n = L.shape[0]
    s = float(B.diagonal().mean())
    Bs = sp.csr_matrix(B / s)
    if n <= 200:
        return float(scipy.linalg.eigh(L.toarray(), Bs.toarray(), eigvals_only=True)[-1]) / s
    solve = _mass_solver(Bs, backend)
    v0 = 1.0 + np.random.default_rng(0).random(n)
    try:
        lam = eigsh(sp.csr_matrix(L), k=1, M=Bs, Minv=LinearOperator((n, n), matvec=solve, dtype=np.float64),
                    which="LA", tol=1e-10, v0=v0, maxiter=20 * n, return_eigenvectors=False)
    except ArpackNoConvergence as e:
        raise SolverError(f"the largest rate of the mesh (for the explicit step's limit) did not converge ({e}): "
                          "use scheme='implicit'") from None
    return float(lam[-1]) / s


def explicit_step_limit(rate: float) -> float:
    """The largest stable step of the explicit scheme (8) for the largest rate ``λ_max`` of
    ``B⁻¹L``: ``4 / λ_max``.

    The project's time convention is the paper's, ``K_t = exp(-(t/2) B⁻¹L)`` (``e^{-λ t/2}`` per
    mode, :mod:`o3dheat.spectral.kernel`), so the heat equation is ``B F' = -L F / 2`` and eq. (8),
    ``F ← F - (dt/2) B⁻¹L F``, multiplies the mode of rate λ by ``1 - λ dt / 2``: stable
    (``|1 - λ dt/2| <= 1`` for every λ in [0, λ_max]) exactly when ``dt <= 4 / λ_max``. (With a
    peer's ``e^{-λ t}`` it would be ``2 / λ_max``, the same step in their time ``t / 2``.)

    Examples
    --------
    >>> from o3dheat.spectral.diffusion import explicit_step_limit
    >>> explicit_step_limit(1000.0)
    0.004
    """
    return 4.0 / rate if rate > 0 else np.inf


def _mass_solver(B, backend):
    """``b -> B⁻¹ b``: a division for a diagonal mass, one factorization otherwise."""
    d = B.diagonal()
    if sp.csc_matrix(B - sp.diags(d)).count_nonzero() == 0:
        return lambda b: b / (d[:, None] if b.ndim == 2 else d)
    return factorize(B, backend=backend).solve


def diffuse(mesh: MeshLike, f: FieldLike, dt: float, steps: int, scheme: str = "explicit", mass: str = "consistent",
            backend: str = "auto", return_history: bool = False) -> np.ndarray:
    """Diffuse per-vertex fields by time stepping (paper eq. (8), or backward Euler).

    Parameters
    ----------
    mesh : o3d.t.geometry.TriangleMesh, o3d.geometry.TriangleMesh or (V, F) tuple
        The surface, repaired for the FEM by :func:`o3dheat.geometry.welding.prepare` (not modified).
    f : (n,) or (n, c) array_like
        Initial field(s).
    dt : float
        Time step (> 0), paper convention (the final time is ``steps * dt``, comparable with
        :meth:`HeatKernel.smooth`).
    steps : int
        Number of steps (>= 0).
    scheme : str
        One of :data:`SCHEMES`. "explicit" is eq. (8); it is stable only for ``dt <= 4 / λ_max``
        (:func:`explicit_step_limit`; ``λ_max`` the largest eigenvalue of ``L x = λ B x``, computed
        to about 1e-10), checked beforehand: a larger dt raises :class:`MeshError` naming that
        limit. "implicit" is unconditionally stable.
    mass : str
        ``B``, a key of :data:`o3dheat.spectral.fem.MASS_KINDS`: "consistent" is the paper's; the steps
        converge to the heat kernel of the variant with this mass
        (:data:`o3dheat.spectral.variants.VARIANTS`, e.g. "identity": the paper's "B := I" kernel).
    backend : str
        Factorization backend (:func:`o3dheat.spectral.linalg.factorize`).
    return_history : bool
        Also return every step: shape ``(n, steps + 1)`` or ``(n, c, steps + 1)``.

    Returns
    -------
    ndarray
        The field(s) at time ``steps * dt`` (0 at unreferenced vertices), or the history.

    Examples
    --------
    >>> import numpy as np, open3d as o3d, o3dheat
    >>> mesh = o3d.t.geometry.TriangleMesh.create_sphere(1.0, 16)
    >>> z = mesh.vertex.positions.numpy()[:, 2]
    >>> g = o3dheat.diffuse(mesh, z, dt=0.01, steps=50, scheme="implicit")
    >>> bool(np.abs(g).max() < np.abs(z).max())
    True
    """
    if not isinstance(scheme, str) or scheme not in SCHEMES:
        raise MeshError(f"unknown scheme {scheme!r}: use one of {', '.join(SCHEMES)}")
    fem.check_mass_kind(mass)
    if (isinstance(dt, bool) or not isinstance(dt, (int, float, np.integer, np.floating))
            or not (np.isfinite(dt) and dt > 0)):
        raise MeshError(f"dt must be a positive number, got {dt!r}")
    steps = checks.count(steps, "steps", minimum=0)
    prep = prepare(mesh)
    f = checks.field(f, prep.n_input)
    F = prep.restrict(f).copy()
    L, B, _ = fem.operators(prep.V, prep.F, mass)
    history = [F.copy()] if return_history else None
    if scheme == "explicit":
        solve = _mass_solver(B, backend)
        lam_max = _largest_rate(L, B, backend)
        limit = explicit_step_limit(lam_max)  # the one number of the check and of its message
        if dt > limit:
            raise MeshError(f"explicit scheme unstable for dt={dt:.6g}: the largest stable step here is "
                            f"4/λ_max = {limit:.6g} (λ_max = {lam_max:.6g}, the largest rate of B⁻¹L); use "
                            "dt <= that or scheme='implicit'")
        A = B - (0.5 * dt) * L
        for _ in range(steps):
            F = solve(A @ F)
            if history is not None:
                history.append(F.copy())
    else:
        solve = factorize(sp.csc_matrix(B + (0.5 * dt) * L), backend=backend).solve
        for _ in range(steps):
            F = solve(B @ F)
            if history is not None:
                history.append(F.copy())
    if not np.all(np.isfinite(F)):
        raise SolverError("time stepping produced non-finite values")
    out = np.stack(history, axis=-1) if history is not None else F
    return prep.expand(out)
