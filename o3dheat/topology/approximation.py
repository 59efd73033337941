"""Feature-driven approximation and the scale hierarchy: :func:`feature_driven`, :func:`scale_space`, :func:`project`.

Notes
-----
* ``pr_A`` (:func:`project`) keeps the values of f on a vertex set A and zeroes the rest;
  ``f_glob = Φ_t(pr_A f)`` and ``f_loc = f − f_glob`` (:func:`feature_driven`). By linearity
  ``f_glob = Σ_{i∈A} f_i Φ_t(e_i)``, computed as one smoothing (no canonic basis is formed), and
  ``Φ_t(pr_A f) + Φ_t(pr_{A^C} f) = Φ_t f``.
* :func:`scale_space` evaluates the hierarchy ``{Φ_t f}`` at the paper's scales with its
  approximation errors, the variation between consecutive scales and the critical points of
  every scale, and tells where each stop criterion of §3.1 holds.

Both take the spectral kernel (:class:`o3dheat.HeatKernel <o3dheat.spectral.kernel.HeatKernel>`, the paper's truncated ``X_k D_t X_kᵀ W``)
or the full one (:class:`o3dheat.HeatFlow <o3dheat.spectral.heatflow.HeatFlow>`, ``exp(−(t/2) W⁻¹L)`` without truncation): the same
computation, with the smoothing each gives.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from o3dheat import checks
from o3dheat.errors import MeshError
from o3dheat.spectral import HeatFlow, HeatKernel
from o3dheat.typing import FieldLike, TimesLike

from .critical import critical_points
from .surface import Surface
from .tracking import Tracks, track_critical_points

__all__ = ["project", "feature_driven", "scale_space", "ScaleSpace"]

log = logging.getLogger("o3dheat")

STOPS = (None, "linf", "critical_points", "tracks")


def project(f: FieldLike, A: ArrayLike) -> np.ndarray:
    """The projection ``pr_A``: f on the vertex set A, 0 elsewhere (§3.3).

    Parameters
    ----------
    f : (n,) or (n, c) array_like
        The field(s), one row per vertex.
    A : sequence of int or (n,) bool array_like
        Vertex indices (repeats allowed) or a mask.

    Returns
    -------
    ndarray of the shape of f (float64)

    Examples
    --------
    >>> from o3dheat.topology.approximation import project
    >>> project([1.0, 2.0, 3.0], [0, 2]).tolist()
    [1.0, 0.0, 3.0]
    """
    f = checks.field(f).copy()
    mask = checks.vertex_set(A, len(f))
    f[~mask] = 0.0
    return f


def feature_driven(kernel: HeatKernel | HeatFlow, f: FieldLike, A: ArrayLike,
                   t: TimesLike) -> tuple[np.ndarray, np.ndarray]:
    """Feature-driven approximation: ``f_glob = Φ_t(pr_A f)`` and ``f_loc = f − f_glob`` (§3.3).

    Parameters
    ----------
    kernel : HeatKernel or HeatFlow
        The spectral kernel or the full one.
    f : (n,) or (n, c) array_like
        The field(s), one row per vertex of the kernel's mesh.
    A : sequence of int or (n,) bool array_like
        The feature vertices, for example ``o3dheat.simplify_critical_points(mesh, f, delta)``.
    t : float or (T,) array_like
        Time(s) (paper convention, >= 0).

    Returns
    -------
    f_glob, f_loc : ndarray
        Shapes as :meth:`HeatKernel.smooth` gives them ((n,), (n, c), (n, T) or (n, c, T)).

    Examples
    --------
    >>> import numpy as np, open3d as o3d, o3dheat
    >>> mesh = o3d.t.geometry.TriangleMesh.create_sphere(1.0, 20)
    >>> K = o3dheat.HeatKernel(o3dheat.eigensolve(mesh, k=30))
    >>> f = mesh.vertex.positions.numpy()[:, 2]
    >>> A = o3dheat.simplify_critical_points(mesh, f)
    >>> g, l = o3dheat.feature_driven(K, f, A, K.scales()[0])
    >>> bool(np.allclose(g + l, f))
    True
    """
    _check_kernel(kernel)
    f = checks.field(f, kernel.n)
    glob = kernel.smooth(project(f, A), t)
    loc = (f[..., None] if glob.ndim > f.ndim else f) - glob
    return glob, loc


def _check_kernel(kernel):
    if not isinstance(kernel, (HeatKernel, HeatFlow)):
        raise MeshError(f"kernel must be a HeatKernel or a HeatFlow, got {type(kernel).__name__}")


@dataclass(frozen=True)
class ScaleSpace:
    """The hierarchy ``{Φ_t f}`` at a sequence of scales (see :func:`scale_space`).

    Attributes
    ----------
    scales : (T,) float64 ndarray
    fields : (n, T) float64 ndarray
        ``Φ_{t_i} f``.
    errors : (T,) float64 ndarray
        ``ε∞ = ‖f − Φ_t f‖∞ / ‖f‖∞`` per scale.
    variation : (T − 1,) float64 ndarray
        ``‖Φ_{t_{i+1}} f − Φ_{t_i} f‖∞`` (units of f).
    critical_counts : (T, 3) int64 ndarray
        (minima, saddles with multiplicity, maxima) per scale; -1 when the mesh is not a
        2-manifold (critical points undefined).
    critical : list of CriticalPoints or None
        The critical points of every scale (None on a non-manifold mesh).
    stop : str or None
        The criterion used.
    tol : float or None
        Its threshold (``stop="linf"``).
    stop_index : int
        First scale ``j >= 1`` where the criterion holds (``variation[j − 1] < tol``, or the same
        critical points at ``j − 1`` and ``j``); the last scale when it never holds or when
        ``stop`` is None.
    stopped : bool
        Whether the criterion held.
    tracks : Tracks or None
        The critical points followed across the scales (:func:`o3dheat.track_critical_points <o3dheat.topology.tracking.track_critical_points>`),
        with ``stop="tracks"``. A kernel carries faces, not positions: its saddles are matched only
        where they stay on their vertex (the stop rule reads the extrema only); for tracks with
        moving saddles and positions, call :func:`o3dheat.track_critical_points <o3dheat.topology.tracking.track_critical_points>` on the mesh.

    Examples
    --------
    >>> import open3d as o3d, o3dheat
    >>> mesh = o3d.t.geometry.TriangleMesh.create_sphere(1.0, 10)
    >>> K = o3dheat.HeatKernel(o3dheat.eigensolve(mesh, k=20))
    >>> z = mesh.vertex.positions.numpy()[:, 2]
    >>> ss = o3dheat.scale_space(K, z, K.scales(5, grid="log"), stop="critical_points")
    >>> ss.fields.shape, ss.errors.round(2).tolist()        # ε∞ grows with the scale
    ((182, 5), [0.04, 0.12, 0.35, 0.76, 0.99])
    >>> ss.critical_counts[0].tolist(), ss.stop_index, ss.stopped, ss.field.shape
    ([1, 0, 1], 1, True, (182,))
    """

    scales: np.ndarray
    fields: np.ndarray
    errors: np.ndarray
    variation: np.ndarray
    critical_counts: np.ndarray
    critical: list | None
    stop: str | None
    tol: float | None
    stop_index: int
    stopped: bool
    tracks: Tracks | None = None

    @property
    def field(self) -> np.ndarray:
        """The field at the stop scale, ``fields[:, stop_index]``."""
        return self.fields[:, self.stop_index]


def scale_space(kernel: HeatKernel | HeatFlow, f: FieldLike, scales: TimesLike | None = None,
                stop: str | None = None, tol: float | None = None) -> ScaleSpace:
    """The multi-scale hierarchy of a field with the stop criteria of §3.1.

    Parameters
    ----------
    kernel : HeatKernel or HeatFlow
        The spectral kernel (its spectrum from :func:`o3dheat.eigensolve <o3dheat.spectral.spectrum.eigensolve>`, which carries the
        faces) or the full one (:class:`o3dheat.HeatFlow <o3dheat.spectral.heatflow.HeatFlow>`).
    f : (n,) array_like
        The scalar field.
    scales : (T,) array_like, optional
        Increasing times >= 0; default ``kernel.scales()`` (the paper's ten; for a HeatFlow
        that computes the 100 eigenvalues that define them).
    stop : {None, "linf", "critical_points", "tracks"}
        "linf": stop when ``‖Φ_{t_{i+1}} f − Φ_{t_i} f‖∞ < tol``; "critical_points": stop when
        two consecutive scales have the same critical points (minima, saddles with
        multiplicity, maxima); "tracks": stop when no extremum is born or dies between two
        consecutive scales (the critical points followed along the gradient flow,
        :func:`o3dheat.track_critical_points <o3dheat.topology.tracking.track_critical_points>`: they may move, as they do under smoothing, where
        "critical_points" asks for the same vertices; by the Morse relation the saddles' count
        is then the same too).
    tol : float, optional
        Threshold of "linf" in the units of f; default ``1e-3 · ‖f‖∞``.

    Returns
    -------
    ScaleSpace

    Examples
    --------
    >>> import numpy as np, open3d as o3d, o3dheat
    >>> mesh = o3d.t.geometry.TriangleMesh.create_sphere(1.0, 20)
    >>> K = o3dheat.HeatKernel(o3dheat.eigensolve(mesh, k=30))
    >>> z = mesh.vertex.positions.numpy()[:, 2]
    >>> noisy = z + 0.1 * np.random.default_rng(0).standard_normal(len(z))
    >>> o3dheat.critical_points(mesh, noisy).counts          # (minima, saddles, maxima) of f
    (68, 132, 66)
    >>> ss = o3dheat.scale_space(K, noisy, stop="critical_points")
    >>> ss.fields.shape, ss.critical_counts[0].tolist(), ss.stop_index
    ((762, 10), [1, 0, 1], 1)

    With 30 eigenpairs the truncation has smoothed everything at every scale; the full kernel at
    the same times shows the hierarchy:

    >>> ex = o3dheat.scale_space(o3dheat.HeatFlow(mesh), noisy, scales=ss.scales, stop="critical_points")
    >>> ss.critical_counts.sum(axis=1).tolist()
    [2, 2, 2, 2, 2, 2, 2, 2, 2, 2]
    >>> ex.critical_counts.sum(axis=1).tolist(), ex.stop_index
    ([40, 10, 4, 2, 2, 2, 2, 2, 2, 2], 4)
    """
    _check_kernel(kernel)
    if stop not in STOPS:
        raise MeshError(f"unknown stop criterion {stop!r}: use one of {STOPS}")
    f = checks.field(f, kernel.n)
    if f.ndim != 1:
        raise MeshError("scale_space takes one scalar field of shape (n,)")
    t = kernel.scales() if scales is None else checks.times(scales)
    t = np.atleast_1d(t).astype(np.float64)
    if t.size == 0 or np.any(np.diff(t) <= 0):
        raise MeshError("scales must be a non-empty, strictly increasing sequence of times")
    if tol is not None and stop != "linf":
        raise MeshError("tol is the threshold of stop='linf' only")
    if stop == "linf":
        tol = 1e-3 * float(np.abs(f).max()) if tol is None else float(tol)
        if not (np.isfinite(tol) and tol >= 0):
            raise MeshError(f"tol must be a finite number >= 0, got {tol}")
    F = kernel.smooth(f, t)
    nf = float(np.abs(f).max())
    with np.errstate(over="ignore"):
        errors = np.abs(F - f[:, None]).max(axis=0) / nf if nf > 0 else np.zeros(len(t))
    variation = np.abs(np.diff(F, axis=1)).max(axis=0) if len(t) > 1 else np.zeros(0)
    faces = kernel.spectrum.faces if isinstance(kernel, HeatKernel) else kernel.faces
    critical, counts = _critical_per_scale(kernel.n, faces, F, required=stop in ("critical_points", "tracks"))
    T = len(t)
    hits, tracks = [], None
    if stop == "linf":
        hits = [j for j in range(1, T) if variation[j - 1] < tol]
    elif stop == "critical_points":
        hits = [j for j in range(1, T) if critical[j].same_as(critical[j - 1])]
    elif stop == "tracks":
        tracks = track_critical_points(Surface.from_faces(kernel.n, faces), F, t)
        changed = {e["scale"] for e in tracks.events if np.any(tracks.kind[e["tracks"]] != "saddle")}
        hits = [j for j in range(1, T) if j - 1 not in changed]
    stopped = bool(hits)
    return ScaleSpace(t, F, errors, variation, counts, critical, stop, tol,
                      hits[0] if stopped else T - 1, stopped, tracks)


def _critical_per_scale(n, faces, F, required):
    T = F.shape[1]
    if faces is None:
        raise MeshError("this kernel carries no faces (a Spectrum made by hand, or operators built elsewhere): "
                        "use o3dheat.eigensolve or o3dheat.HeatFlow on a mesh")
    try:
        S = Surface.from_faces(n, faces)
    except MeshError as e:
        if required:
            raise MeshError(f"this stop criterion needs a 2-manifold mesh: {e}") from e
        log.warning("critical points are not computed (%s); critical_counts is -1", e)
        return None, np.full((T, 3), -1, np.int64)
    critical = [critical_points(S, F[:, i]) for i in range(T)]
    return critical, np.array([c.counts for c in critical], dtype=np.int64).reshape(T, 3)
