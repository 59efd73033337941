"""The ``wks`` filter: wave kernel signatures."""

from __future__ import annotations

from dataclasses import dataclass

from o3dheat.pipelines.site import Normalization, Operators, Site, Variant, checked, eigenpairs, kernel_of, param
from o3dheat.spectral.variants import mass_of


@dataclass(frozen=True)
class Wks:
    """Wave kernel signatures (Aubry, Schlickewei & Cremers 2011) on the kernel's spectrum -> ``wks`` (n, E).

    Parameters
    ----------
    energies : int
        Number of log-energies, evenly spaced from ``log λ_2`` to ``log λ_k / 1.02`` (Aubry's;
        :func:`o3dheat.spectral.signatures.wks_energies`), 2 to 100000.
    sigma : float or None
        Width of the filters in log-energy (> 0); None: Aubry's, 6 times the spacing of the energies.
    variant : str
        The kernel, a key of :data:`o3dheat.spectral.variants.VARIANTS` (each on the spectrum of its
        own mass; "weighted" is the paper's).
    normalize : None or str
        One of :data:`o3dheat.spectral.variants.NORMALIZATIONS`; "lambda2": eigenvalues over λ_2
        (the log-energies then do not depend on the size of the shape).
    k : int
        Eigenpairs (>= 1; capped at what the mesh has, with a warning).
    output : str
        Attribute name.
    operators : {"reconstruct", "robust"}
        For point clouds.

    Examples
    --------
    >>> import open3d as o3d, o3dheat.pipelines.filters as flt
    >>> out = flt.apply(o3d.t.geometry.TriangleMesh.create_sphere(1.0, 10), "wks", k=20, energies=6)
    >>> out.vertex["wks"].shape
    SizeVector[182, 6]
    """

    energies: int = param(100, ge=2, le=100_000)
    sigma: float | None = param(None, gt=0)
    variant: Variant = "weighted"
    normalize: Normalization = None
    k: int = eigenpairs()
    output: str = "wks"
    operators: Operators = "reconstruct"

    outputs = ("wks",)

    def __post_init__(self):
        checked(self)
        mass_of(self.variant)  # an unknown variant: MeshError listing o3dheat.spectral.variants.VARIANTS

    def plan(self, columns: dict[str, int]) -> dict[str, int]:
        """What this filter writes, given the input's attributes (see :meth:`o3dheat.pipelines.filters.Chain.check`).

        Examples
        --------
        >>> import o3dheat.pipelines.filters as flt
        >>> flt.get("wks", energies=16).plan({"positions": 3})
        {'wks': 16}
        """
        return {self.output: self.energies}

    def __call__(self, geometry):
        """Wave kernel signatures (see the class docstring).

        Parameters
        ----------
        geometry : Open3D TriangleMesh or PointCloud (legacy or tensor), (V, F) pair or mesh-like
            The input; it is not modified.

        Returns
        -------
        open3d.t.geometry.TriangleMesh or open3d.t.geometry.PointCloud
            A copy of the input (tensor geometry) with ``output`` added: (n, energies).
        """
        site = Site(geometry, self.operators, step=self)
        K = kernel_of(site, self.k, self.variant, self.normalize)
        site.set(self.output, site.from_surface(K.wks(self.energies, self.sigma)))
        return site.result()
