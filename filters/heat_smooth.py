"""The ``heat_smooth`` filter: Φ_t of an attribute."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

from o3dheat.errors import MeshError

from ._common import Grid, Site, Variant, kernel_of, times_of


@dataclass(frozen=True)
class HeatSmooth:
    """Smooth a vertex attribute with the heat kernel: ``Φ_t f = X D_t Xᵀ W f`` (paper eq. (5)).

    Parameters
    ----------
    attribute : str
        The field; a multi-column attribute needs ``column`` when several times are asked.
    column : int or None
        One column of a multi-column attribute.
    times : list of float or None
        Times (paper convention ``exp(−λ t / 2)``). Default: the paper's ``scales``.
    scales : int
        Number of scales of ``grid`` when ``times`` is not given.
    grid : {"paper", "log"}
        "paper": ``t_i = (i / scales) / λ_k``; "log": from ``1/λ_k`` to ``2 ln(100)/λ_2`` (the
        whole range, to nearly constant). See :meth:`o3dheat.HeatKernel.scales`.
    variant : {"weighted", "linear", "voronoi", "lumped"}
        The kernel, each on the spectrum of its own mass (:data:`o3dheat.kernel.VARIANTS`;
        "weighted" is the paper's).
    normalize : {None, "lambda2"}
        "lambda2": the scale-invariant kernel.
    k : int
        Eigenpairs.
    output : str or None
        Default "<attribute>_smooth": (n,) for one time, (n, T) for T times.
    operators : {"reconstruct", "robust"}
        For point clouds.

    Examples
    --------
    >>> import open3d as o3d, o3dheat.filters as flt
    >>> m = flt.apply(o3d.t.geometry.TriangleMesh.create_sphere(1.0, 20), "scalar", kind="height")
    >>> flt.apply(m, "heat_smooth", attribute="height", k=30).vertex["height_smooth"].shape
    SizeVector[762, 10]
    """

    attribute: str = "height"
    column: int | None = None
    times: tuple[float, ...] | None = None
    scales: int = 10
    grid: Grid = "paper"
    variant: Variant = "weighted"
    normalize: Literal[None, "lambda2"] = None
    k: int = 100
    output: str | None = None
    operators: Literal["reconstruct", "robust"] = "reconstruct"

    outputs = ("<attribute>_smooth",)

    def __post_init__(self):
        if self.k < 1 or self.scales < 1:
            raise MeshError("k and scales must be positive")
        if self.times is not None and any(t < 0 for t in self.times):
            raise MeshError("times must be >= 0")

    def __call__(self, geometry):
        site = Site(geometry, self.operators)
        f = site.attribute(self.attribute, self.column)
        K = kernel_of(site, self.k, self.variant, self.normalize)
        t = times_of(K, self.times, self.scales, self.grid)
        if f.ndim == 2 and len(t) > 1:
            raise MeshError(f"attribute {self.attribute!r} has {f.shape[1]} columns: smooth one column "
                            "(column=) at several times, or all columns at one time")
        g = K.smooth(site.to_surface(f), t if len(t) > 1 else float(t[0]))
        site.set(self.output or f"{self.attribute}_smooth", site.from_surface(g))
        return site.result()
