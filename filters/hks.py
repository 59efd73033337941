"""The ``hks`` filter: heat kernel signatures."""

from __future__ import annotations

from dataclasses import dataclass

from o3dheat.pipelines.site import (
    Grid,
    HksForm,
    Normalization,
    Operators,
    Site,
    Variant,
    checked,
    eigenpairs,
    kernel_of,
    scale_count,
    time_count,
    time_list,
    times_of,
)
from o3dheat.spectral.variants import HKS_DEFAULT, mass_of


@dataclass(frozen=True)
class Hks:
    """Heat kernel signatures at several scales (paper §2.2) -> ``hks`` (n, T).

    Parameters
    ----------
    scales : int
        Number of scales of ``grid`` when ``times`` is not given (1 to 100000).
    grid : str
        The scale grid, one of :data:`o3dheat.spectral.variants.GRIDS` (:meth:`o3dheat.HeatKernel.scales <o3dheat.spectral.kernel.HeatKernel.scales>`).
    times : list of float or None
        Times (paper convention ``exp(−λ t / 2)``), at least one, each >= 0; None: ``scales``
        times of ``grid``.
    form : str
        One of :data:`o3dheat.spectral.variants.HKS_FORMS`: "density" (the default everywhere,
        :data:`o3dheat.spectral.variants.HKS_DEFAULT`): ``Σ e^{−λt/2} x(i)²`` (the usual HKS, stable across
        samplings); "paper": the kernel diagonal ``Σ e^{−λt/2} x(i) (W x)(i)``.
    variant : str
        The kernel, a key of :data:`o3dheat.spectral.variants.VARIANTS` (each on the spectrum of its own mass;
        "weighted" is the paper's).
    normalize : None or str
        One of :data:`o3dheat.spectral.variants.NORMALIZATIONS`; "lambda2": scale-invariant eigenvalues.
    k : int
        Eigenpairs (>= 1; capped at what the mesh has, with a warning).
    output : str
        Attribute name.
    operators : {"reconstruct", "robust"}
        For point clouds.

    Examples
    --------
    >>> import open3d as o3d, o3dheat.pipelines.filters as flt
    >>> out = flt.apply(o3d.t.geometry.TriangleMesh.create_sphere(1.0, 10), "hks", k=20, scales=4)
    >>> out.vertex["hks"].shape
    SizeVector[182, 4]
    """

    scales: int = scale_count()
    times: tuple[float, ...] | None = time_list()
    grid: Grid = "paper"
    form: HksForm = HKS_DEFAULT
    variant: Variant = "weighted"
    normalize: Normalization = None
    k: int = eigenpairs()
    output: str = "hks"
    operators: Operators = "reconstruct"

    outputs = ("hks",)

    def __post_init__(self):
        checked(self)
        mass_of(self.variant)  # an unknown variant: MeshError listing o3dheat.spectral.variants.VARIANTS

    def plan(self, columns: dict[str, int]) -> dict[str, int]:
        """What this filter writes, given the input's attributes (see :meth:`o3dheat.pipelines.filters.Chain.check`).

        Examples
        --------
        >>> import o3dheat.pipelines.filters as flt
        >>> flt.get("hks", scales=4).plan({"positions": 3})
        {'hks': 4}
        """
        return {self.output: time_count(self.times, self.scales)}

    def __call__(self, geometry):
        """Heat kernel signatures (see the class docstring).

        Parameters
        ----------
        geometry : Open3D TriangleMesh or PointCloud (legacy or tensor), (V, F) pair or mesh-like
            The input; it is not modified.

        Returns
        -------
        open3d.t.geometry.TriangleMesh or open3d.t.geometry.PointCloud
            A copy of the input (tensor geometry) with ``output`` added: (n, T), one column per time.
        """
        site = Site(geometry, self.operators, step=self)
        K = kernel_of(site, self.k, self.variant, self.normalize)
        t = times_of(K, self.times, self.scales, self.grid)
        h = K.hks(t, form=self.form)
        site.set(self.output, site.from_surface(h.reshape(len(h), -1)))
        return site.result()
