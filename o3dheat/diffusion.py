"""Time stepping of the heat equation ``B ∂_t F = −L F / 2`` (paper §2.3): the explicit scheme of
eq. (8), ``B F(t+dt) = (B − dt L / 2) F(t)``, and backward (implicit) Euler,
``(B + dt L / 2) F(t+dt) = B F(t)``. Either way one matrix is factorized once for all steps, and
many fields are stepped at once.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from . import fem
from . import checks
from .errors import MeshError, SolverError
from .linalg import factorize
from .mesh import prepare

__all__ = ["diffuse", "SCHEMES"]

#: time-stepping schemes of :func:`diffuse`: eq. (8) and backward Euler
SCHEMES = ("explicit", "implicit")


def _largest_rate(L, B_solve, n, iters=40, seed=0):
    """Power iteration for the largest eigenvalue of B^{-1} L (a lower bound, slightly raised)."""
    x = np.random.default_rng(seed).standard_normal(n)
    lam = 0.0
    for _ in range(iters):
        y = B_solve(L @ x)
        top = float(np.abs(y).max())
        if top == 0:
            return 0.0
        nrm = top * np.linalg.norm(y / top)  # no overflow of the squares on tiny meshes (rate ~ 1/h²)
        lam = nrm / np.linalg.norm(x)
        x = y / nrm
    return 1.05 * lam


def _mass_solver(B, backend):
    """``b -> B⁻¹ b``: a division for a diagonal mass, one factorization otherwise."""
    d = B.diagonal()
    if sp.csc_matrix(B - sp.diags(d)).count_nonzero() == 0:
        return lambda b: b / (d[:, None] if b.ndim == 2 else d)
    return factorize(B, backend=backend).solve


def diffuse(mesh, f, dt, steps, scheme="explicit", mass="consistent", backend="auto",
            return_history=False):
    """Diffuse per-vertex fields by time stepping (paper eq. (8), or backward Euler).

    Parameters
    ----------
    mesh : o3d.t.geometry.TriangleMesh, o3d.geometry.TriangleMesh or (V, F) tuple
    f : (n,) or (n, c) array_like
        Initial field(s).
    dt : float
        Time step (> 0), paper convention (the final time is ``steps * dt``, comparable with
        :meth:`HeatKernel.smooth`).
    steps : int
        Number of steps (>= 0).
    scheme : str
        One of :data:`SCHEMES`. "explicit" is eq. (8); it is stable only for ``dt <= 4 / λ_max``, checked beforehand
        (a larger dt raises :class:`MeshError` naming the largest stable one). "implicit" is
        unconditionally stable.
    mass : str
        ``B``, a key of :data:`o3dheat.fem.MASS_KINDS`: "consistent" is the paper's; the steps
        converge to the heat kernel of the variant with this mass
        (:data:`o3dheat.kernel.VARIANTS`, e.g. "identity": the paper's "B := I" kernel).
    backend : str
        Factorization backend (:func:`o3dheat.linalg.factorize`).
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
    if not (np.isscalar(dt) and np.isfinite(dt) and dt > 0):
        raise MeshError(f"dt must be a positive number, got {dt!r}")
    steps = checks.count(steps, "steps", minimum=0)
    prep = prepare(mesh)
    f = checks.field(f, prep.n_input)
    F = prep.restrict(f).copy()
    L, B, _ = fem.operators(prep.V, prep.F, mass)
    r = len(prep.V)
    history = [F.copy()] if return_history else None
    if scheme == "explicit":
        solve = _mass_solver(B, backend)
        lam_max = _largest_rate(L, solve, r)
        if dt * lam_max > 4.0:
            raise MeshError(f"explicit scheme unstable for dt={dt:g}: the largest stable step here is "
                            f"about {4.0 / lam_max:.3g}; use a smaller dt or scheme='implicit'")
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
