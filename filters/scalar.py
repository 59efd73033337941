"""The ``scalar`` filter: make a field to study."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np

from o3dheat.errors import MeshError
from o3dheat.geometry import prepare
from o3dheat.pipelines.site import (
    Operators,
    Site,
    checked,
    need_attribute,
    param,
)
from o3dheat.spectral import fem


@dataclass(frozen=True)
class Scalar:
    """Make a scalar field: height, mean or Gaussian curvature, or noise added to an attribute.

    Parameters
    ----------
    kind : {"height", "mean_curvature", "gaussian_curvature", "noise"}
        "height": the coordinate along ``axis``; "mean_curvature": ``½ ⟨A⁻¹ L x, n⟩`` from the FEM
        operators (1/R on a sphere of radius R); "gaussian_curvature": the angle defect over the
        Voronoi area (1/R²); "noise": ``attribute`` plus seeded Gaussian noise.
    axis : int
        0, 1 or 2 for x, y, z (height).
    attribute : str or None
        The attribute to perturb (noise).
    sigma : float
        Standard deviation of the noise relative to the attribute's range (max − min), >= 0.
    seed : int
        Seed of the noise, >= 0 (numpy's generators take no negative seed).
    output : str or None
        Name of the new attribute; default the kind ("height", "mean_curvature",
        "gaussian_curvature") or "<attribute>_noisy".
    operators : {"reconstruct", "robust"}
        For point clouds: how the surface quantities are computed (see the filters guide).

    Examples
    --------
    >>> import open3d as o3d, o3dheat.pipelines.filters as flt
    >>> out = flt.apply(o3d.t.geometry.TriangleMesh.create_sphere(1.0, 20), "scalar", kind="gaussian_curvature")
    >>> round(float(out.vertex["gaussian_curvature"].numpy().mean()), 1)
    1.0
    """

    kind: Literal["height", "mean_curvature", "gaussian_curvature", "noise"] = "height"
    axis: int = param(2, ge=0, le=2)
    attribute: str | None = None
    sigma: float = param(0.05, ge=0)
    seed: int = param(0, ge=0)
    output: str | None = None
    operators: Operators = "reconstruct"

    outputs = ("<output>",)

    def __post_init__(self):
        checked(self)
        if self.kind == "noise" and not self.attribute:
            raise MeshError("kind='noise' needs attribute= (the field to perturb)")

    def plan(self, columns: dict[str, int]) -> dict[str, int]:
        """What this filter writes, given the input's attributes (see :meth:`o3dheat.pipelines.filters.Chain.check`).

        Examples
        --------
        >>> import o3dheat.pipelines.filters as flt
        >>> flt.get("scalar", kind="noise", attribute="positions").plan({"positions": 3})
        {'positions_noisy': 3}
        """
        if self.kind == "noise":
            return {self.output or f"{self.attribute}_noisy": need_attribute(columns, self.attribute)}
        return {self.output or ("height" if self.kind == "height" else self.kind): 1}

    def __call__(self, geometry):
        """Make the field (see the class docstring).

        Parameters
        ----------
        geometry : Open3D TriangleMesh or PointCloud (legacy or tensor), (V, F) pair or mesh-like
            The input (holding ``attribute`` for "noise"); it is not modified.

        Returns
        -------
        open3d.t.geometry.TriangleMesh or open3d.t.geometry.PointCloud
            A copy of the input (tensor geometry) with the field added: (n,), or the shape of
            ``attribute`` for "noise"; named ``output``, else the kind or "<attribute>_noisy".
        """
        site = Site(geometry, self.operators, step=self)
        if self.kind == "height":
            values, name = site.P[:, self.axis].copy(), "height"
        elif self.kind == "noise":
            f = site.attribute(self.attribute)
            rng = np.random.default_rng(self.seed)
            span = float(np.ptp(f)) if f.size else 0.0
            values, name = f + self.sigma * (span or 1.0) * rng.standard_normal(f.shape), f"{self.attribute}_noisy"
        else:
            if site.operators == "robust" and not site.is_mesh:
                raise MeshError(f"{self.kind} needs a surface: use operators='reconstruct' for point clouds")
            prep = prepare(site.surface())
            fn = fem.mean_curvature if self.kind == "mean_curvature" else fem.gaussian_curvature
            values, name = site.from_surface(prep.expand(fn(prep.V, prep.F))), self.kind
        site.set(self.output or name, values)
        return site.result()
