"""The ``si_hks`` filter: scale-invariant heat kernel signatures."""

from __future__ import annotations

from dataclasses import dataclass

from o3dheat.pipelines.site import Operators, Site, Variant, checked, eigenpairs, kernel_of, param
from o3dheat.spectral.signatures import SI_HKS_GRID
from o3dheat.spectral.variants import mass_of


@dataclass(frozen=True)
class SiHks:
    """Scale-invariant heat kernel signatures (Bronstein & Kokkinos 2010) -> ``si_hks`` (n, F).

    The density HKS at ``t = alpha^tau`` on a fixed grid of ``tau``, its logarithm, its discrete
    derivative in ``tau`` and the magnitudes of its Fourier transform, the ``frequencies`` lowest
    kept (:func:`o3dheat.spectral.signatures.si_hks`): the same for a shape and a scaled copy.

    Parameters
    ----------
    frequencies : int
        How many of the lowest frequencies are kept (1 to the number of times less one).
    alpha : float
        Base of the times (> 1).
    tau_from, tau_to, tau_step : float
        The grid of ``tau`` (default 1e-12 .. 1e12 in ``t``, steps of a quarter octave): it must
        contain the shape's scale space, or the filter says which grid to use.
    variant : str
        The kernel, a key of :data:`o3dheat.spectral.variants.VARIANTS`.
    k : int
        Eigenpairs (>= 1; capped at what the mesh has, with a warning).
    output : str
        Attribute name.
    operators : {"reconstruct", "robust"}
        For point clouds.

    Examples
    --------
    >>> import open3d as o3d, o3dheat.pipelines.filters as flt
    >>> out = flt.apply(o3d.t.geometry.TriangleMesh.create_sphere(1.0, 10), "si_hks", k=20)
    >>> out.vertex["si_hks"].shape
    SizeVector[182, 8]
    """

    frequencies: int = param(8, ge=1, le=100_000)
    alpha: float = param(SI_HKS_GRID[0], gt=1)
    tau_from: float = SI_HKS_GRID[1]
    tau_to: float = SI_HKS_GRID[2]
    tau_step: float = param(SI_HKS_GRID[3], gt=0)
    variant: Variant = "weighted"
    k: int = eigenpairs()
    output: str = "si_hks"
    operators: Operators = "reconstruct"

    outputs = ("si_hks",)

    def __post_init__(self):
        checked(self)
        mass_of(self.variant)

    def plan(self, columns: dict[str, int]) -> dict[str, int]:
        """What this filter writes, given the input's attributes (see :meth:`o3dheat.pipelines.filters.Chain.check`).

        Examples
        --------
        >>> import o3dheat.pipelines.filters as flt
        >>> flt.get("si_hks", frequencies=6).plan({"positions": 3})
        {'si_hks': 6}
        """
        return {self.output: self.frequencies}

    def __call__(self, geometry):
        """Scale-invariant heat kernel signatures (see the class docstring).

        Parameters
        ----------
        geometry : Open3D TriangleMesh or PointCloud (legacy or tensor), (V, F) pair or mesh-like
            The input; it is not modified.

        Returns
        -------
        open3d.t.geometry.TriangleMesh or open3d.t.geometry.PointCloud
            A copy of the input (tensor geometry) with ``output`` added: (n, frequencies).
        """
        site = Site(geometry, self.operators, step=self)
        K = kernel_of(site, self.k, self.variant)
        grid = (self.alpha, self.tau_from, self.tau_to, self.tau_step)
        site.set(self.output, site.from_surface(K.si_hks(self.frequencies, grid)))
        return site.result()
