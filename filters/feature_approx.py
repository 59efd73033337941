"""The ``feature_approx`` filter: global and local components of an attribute (§3.3)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from o3dheat.errors import MeshError
from o3dheat.pipelines.site import (
    Method,
    Operators,
    Site,
    Variant,
    check_column,
    checked,
    eigenpairs,
    fraction,
    kernel_of,
    need_attribute,
    param,
    persistence,
    smoother,
    tolerance,
)
from o3dheat.spectral.variants import mass_of
from o3dheat.topology import feature_driven, simplify_critical_points, track_critical_points


@dataclass(frozen=True)
class FeatureApprox:
    """Feature-driven approximation: ``<attribute>_glob = Φ_t(pr_A f)`` and ``<attribute>_loc = f −
    <attribute>_glob``, with A the critical points of high persistence (paper §3.3).

    Parameters
    ----------
    attribute : str
        The field.
    column : int or None
        Which column of a multi-column attribute, (n, c) or (n, a, b...) flattened row-major like
        its PLY properties ``<attribute>_0 ..``: 0-based, negative counts from the end (-1 is the
        last). Needed when the attribute has several columns: without it the filter refuses,
        listing the columns (the rule of every filter and of ``o3dheat figure --column``).
    scale : int
        Which of the paper's 10 scales, 1..10 (when ``t`` is not given).
    t : float or None
        Time (paper convention), >= 0.
    delta : float or None
        Persistence threshold of the δ-simplification (units of f, >= 0).
    keep_fraction : float or None
        Alternative to delta, in [0, 1]. With neither, every critical point is a feature.
    lifetime : float or None
        Alternative to delta and keep_fraction (> 0, paper time convention): the features are the
        critical points whose track lives to this time under the heat flow of the field itself
        (:func:`o3dheat.track_critical_points <o3dheat.topology.tracking.track_critical_points>` over 40 log-spaced times up to it, with the
        filter's method and variant; :meth:`o3dheat.Tracks.features <o3dheat.topology.tracking.Tracks.features>`).
    variant : str
        The kernel, a key of :data:`o3dheat.spectral.variants.VARIANTS` (each on the spectrum of its own mass;
        "weighted" is the paper's).
    k : int
        Eigenpairs of the spectral method (>= 1; capped at what the mesh has, with a warning); with
        "exact" they only place the default scale.
    method : str
        One of :data:`o3dheat.spectral.heatflow.METHODS`: "spectral" (the paper's truncated kernel, the
        default) or "exact" (the full kernel, to ``tol``); see the ``heat_smooth`` filter.
    tol : float
        Relative W-norm error of the exact method, in (0, 1).
    operators : {"reconstruct", "robust"}
        For point clouds (only "reconstruct").

    Examples
    --------
    >>> import numpy as np, open3d as o3d, o3dheat.pipelines.filters as flt
    >>> m = flt.apply(o3d.t.geometry.TriangleMesh.create_sphere(1.0, 20), "scalar", kind="height")
    >>> out = flt.apply(m, "feature_approx", attribute="height", k=30, keep_fraction=0.5)
    >>> g, l = out.vertex["height_glob"].numpy(), out.vertex["height_loc"].numpy()
    >>> bool(np.allclose(g + l, out.vertex["height"].numpy()))
    True
    """

    attribute: str = "height"
    column: int | None = None
    scale: int = param(1, ge=1, le=10)
    t: float | None = param(None, ge=0)
    delta: float | None = persistence()
    keep_fraction: float | None = fraction()
    lifetime: float | None = param(None, gt=0)
    variant: Variant = "weighted"
    k: int = eigenpairs()
    method: Method = "spectral"
    tol: float = tolerance()
    operators: Operators = "reconstruct"

    outputs = ("<attribute>_glob", "<attribute>_loc")

    def __post_init__(self):
        checked(self)
        if sum(x is not None for x in (self.delta, self.keep_fraction, self.lifetime)) > 1:
            raise MeshError("give one of delta, keep_fraction and lifetime")
        mass_of(self.variant)  # an unknown variant: MeshError listing o3dheat.spectral.variants.VARIANTS

    def plan(self, columns: dict[str, int]) -> dict[str, int]:
        """What this filter writes, given the input's attributes (see :meth:`o3dheat.pipelines.filters.Chain.check`).

        Examples
        --------
        >>> import o3dheat.pipelines.filters as flt
        >>> flt.get("feature_approx", attribute="height").plan({"positions": 3, "height": 1})
        {'height_glob': 1, 'height_loc': 1}
        """
        check_column(need_attribute(columns, self.attribute), self.attribute, self.column)
        return {f"{self.attribute}_glob": 1, f"{self.attribute}_loc": 1}

    def __call__(self, geometry):
        """The feature-driven approximation (see the class docstring).

        Parameters
        ----------
        geometry : Open3D TriangleMesh or PointCloud (legacy or tensor), (V, F) pair or mesh-like
            The input, holding ``attribute``; it is not modified.

        Returns
        -------
        open3d.t.geometry.TriangleMesh or open3d.t.geometry.PointCloud
            A copy of the input (tensor geometry) with ``<attribute>_glob`` and ``<attribute>_loc``
            added, (n,) each, their sum the field.
        """
        site = Site(geometry, self.operators, step=self)
        f, V, F, g = site.scalar_on_surface(self.attribute, self.column)
        phi = smoother(site, self.method, self.k, self.variant, tol=self.tol)
        if self.lifetime is not None:  # the critical points whose track lives to `lifetime`
            times = np.r_[0.0, np.geomspace(self.lifetime / 1000, self.lifetime, 40)]
            fields = phi.smooth(g, times)
            fields[:, 0] = g  # t = 0 is the field itself (a truncated kernel gives its projection there)
            A = track_critical_points((V, F), fields, times).features()
        else:
            A = simplify_critical_points((V, F), g, delta=self.delta, keep_fraction=self.keep_fraction)
        if self.t is None:  # the paper's scales, from the spectrum
            t = float(kernel_of(site, self.k, variant=self.variant).scales(10)[self.scale - 1])
        else:
            t = self.t
        glob, _ = feature_driven(phi, g, A, t)
        glob = site.from_surface(glob)
        site.set(f"{self.attribute}_glob", glob)
        site.set(f"{self.attribute}_loc", f - glob)
        return site.result()
