"""The ``hks`` filter: heat kernel signatures."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

from o3dheat.errors import MeshError

from ._common import Grid, HksForm, Site, Variant, kernel_of, times_of


@dataclass(frozen=True)
class Hks:
    """Heat kernel signatures at several scales (paper §2.2) -> ``hks`` (n, T).

    Parameters
    ----------
    scales : int
        Number of scales of ``grid`` when ``times`` is not given.
    grid : {"paper", "log"}
        The scale grid (:meth:`o3dheat.HeatKernel.scales`).
    times : list of float or None
        Times (paper convention ``exp(−λ t / 2)``).
    form : {"density", "paper"}
        "density" (the default everywhere): ``Σ e^{−λt/2} x(i)²`` (the usual HKS, stable across
        samplings); "paper": the kernel diagonal ``Σ e^{−λt/2} x(i) (W x)(i)``.
    variant : {"weighted", "linear", "voronoi", "lumped"}
        The kernel, each on the spectrum of its own mass (:data:`o3dheat.kernel.VARIANTS`).
    normalize : {None, "lambda2"}
        "lambda2": scale-invariant eigenvalues.
    k : int
        Eigenpairs.
    output : str
        Attribute name.
    operators : {"reconstruct", "robust"}
        For point clouds.

    Examples
    --------
    >>> import open3d as o3d, o3dheat.filters as flt
    >>> out = flt.apply(o3d.t.geometry.TriangleMesh.create_sphere(1.0, 10), "hks", k=20, scales=4)
    >>> out.vertex["hks"].shape
    SizeVector[182, 4]
    """

    scales: int = 10
    times: tuple[float, ...] | None = None
    grid: Grid = "paper"
    form: HksForm = "density"
    variant: Variant = "weighted"
    normalize: Literal[None, "lambda2"] = None
    k: int = 100
    output: str = "hks"
    operators: Literal["reconstruct", "robust"] = "reconstruct"

    outputs = ("hks",)

    def __post_init__(self):
        if self.k < 1 or self.scales < 1:
            raise MeshError("k and scales must be positive")

    def __call__(self, geometry):
        site = Site(geometry, self.operators)
        K = kernel_of(site, self.k, self.variant, self.normalize)
        t = times_of(K, self.times, self.scales, self.grid)
        h = K.hks(t, form=self.form)
        site.set(self.output, site.from_surface(h.reshape(len(h), -1)))
        return site.result()
