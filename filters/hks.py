"""The ``hks`` filter: heat kernel signatures."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

from o3dheat.errors import MeshError

from ._common import Site, kernel_of, times_of


@dataclass(frozen=True)
class Hks:
    """Heat kernel signatures at several scales (paper §2.2) -> ``hks`` (n, T).

    Parameters
    ----------
    scales : int
        Number of the paper's scales when ``times`` is not given.
    times : list of float or None
        Times (paper convention ``exp(−λ t / 2)``).
    form : {"density", "paper"}
        "density": ``Σ e^{−λt/2} x(i)²`` (the usual HKS, stable across samplings); "paper": the
        kernel diagonal ``Σ e^{−λt/2} x(i) (B x)(i)``.
    normalize : {None, "lambda2"}
        "lambda2": scale-invariant eigenvalues.
    k : int
        Eigenpairs.
    mass : {"consistent", "lumped", "identity"}
        Mass matrix of the eigenproblem.
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
    form: Literal["density", "paper"] = "density"
    normalize: Literal[None, "lambda2"] = None
    k: int = 100
    mass: Literal["consistent", "lumped", "identity"] = "consistent"
    output: str = "hks"
    operators: Literal["reconstruct", "robust"] = "reconstruct"

    outputs = ("hks",)

    def __post_init__(self):
        if self.k < 1 or self.scales < 1:
            raise MeshError("k and scales must be positive")

    def __call__(self, geometry):
        site = Site(geometry, self.operators)
        K = kernel_of(site, self.k, self.mass, normalize=self.normalize)
        t = times_of(K, self.times, self.scales)
        h = K.hks(t, form=self.form)
        site.set(self.output, site.from_surface(h.reshape(len(h), -1)))
        return site.result()
