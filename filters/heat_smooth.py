"""The ``heat_smooth`` filter: Φ_t of an attribute."""

from __future__ import annotations

from dataclasses import dataclass

from o3dheat.errors import MeshError
from o3dheat.pipelines.site import (
    Grid,
    Method,
    Normalization,
    Operators,
    Site,
    Variant,
    check_column,
    checked,
    eigenpairs,
    kernel_of,
    need_attribute,
    scale_count,
    smoother,
    time_count,
    time_list,
    times_of,
    tolerance,
)
from o3dheat.spectral.variants import mass_of


@dataclass(frozen=True)
class HeatSmooth:
    """Smooth a vertex attribute with the heat kernel: ``Φ_t f`` (paper eq. (5)), spectral
    (``X_k D_t X_kᵀ W f``, k eigenpairs) or exact (the full kernel ``exp(−(t/2) W⁻¹L)``).

    Parameters
    ----------
    attribute : str
        The field. A multi-column attribute (n, c) is smoothed column by column at one time
        (``times`` of one value): output (n, c); at several times it needs ``column``.
    column : int or None
        Which column of a multi-column attribute, (n, c) or (n, a, b...) flattened row-major like
        its PLY properties ``<attribute>_0 ..``: 0-based, negative counts from the end (-1 is the
        last). Needed to smooth a multi-column attribute at several times: without it the filter
        refuses, listing the columns (the rule of every filter and of ``o3dheat figure --column``).
    times : list of float or None
        Times (paper convention ``exp(−λ t / 2)``), at least one, each >= 0. Default (None): the
        paper's ``scales``.
    scales : int
        Number of scales of ``grid`` when ``times`` is not given (1 to 100000).
    grid : str
        One of :data:`o3dheat.spectral.variants.GRIDS`. "paper": ``t_i = (i / scales) / λ_k``; "log": from
        ``1/λ_k`` to ``2 ln(100)/λ_2`` (the whole range, to nearly constant). See
        :meth:`o3dheat.HeatKernel.scales <o3dheat.spectral.kernel.HeatKernel.scales>`.
    variant : str
        The kernel, a key of :data:`o3dheat.spectral.variants.VARIANTS` (each on the spectrum of its own mass;
        "weighted" is the paper's).
    normalize : None or str
        One of :data:`o3dheat.spectral.variants.NORMALIZATIONS`; "lambda2": the scale-invariant kernel.
    k : int
        Eigenpairs of the spectral method (>= 1; capped at what the mesh has, with a warning); with
        "exact" they only place the default scales.
    method : str
        One of :data:`o3dheat.spectral.heatflow.METHODS`. "spectral" (the default, the paper's
        computation): the truncated kernel on k eigenpairs, which is band-limited, so that ``k``
        smooths too (at the paper's scales more than ``t`` does). "exact": the full kernel
        (:class:`o3dheat.HeatFlow <o3dheat.spectral.heatflow.HeatFlow>`), to ``tol``: ``t`` alone smooths. Without ``times`` the scales
        still come from the spectrum (the paper's ``t_i = (i/10)/λ_k``); give ``times`` to skip
        the eigensolve.
    tol : float
        Relative W-norm error of the exact method, in (0, 1).
    output : str or None
        Default "<attribute>_smooth": (n,) for one time, (n, T) for T times.
    operators : {"reconstruct", "robust"}
        For point clouds.

    Examples
    --------
    >>> import open3d as o3d, o3dheat.pipelines.filters as flt
    >>> m = flt.apply(o3d.t.geometry.TriangleMesh.create_sphere(1.0, 20), "scalar", kind="height")
    >>> flt.apply(m, "heat_smooth", attribute="height", k=30).vertex["height_smooth"].shape
    SizeVector[762, 10]
    >>> out = flt.apply(m, "heat_smooth", attribute="height", method="exact", times=(0.01, 0.1))
    >>> out.vertex["height_smooth"].shape
    SizeVector[762, 2]
    """

    attribute: str = "height"
    column: int | None = None
    times: tuple[float, ...] | None = time_list()
    scales: int = scale_count()
    grid: Grid = "paper"
    variant: Variant = "weighted"
    normalize: Normalization = None
    k: int = eigenpairs()
    method: Method = "spectral"
    tol: float = tolerance()
    output: str | None = None
    operators: Operators = "reconstruct"

    outputs = ("<attribute>_smooth",)

    def __post_init__(self):
        checked(self)
        mass_of(self.variant)  # an unknown variant: MeshError listing o3dheat.spectral.variants.VARIANTS

    def _columns_out(self, c):
        """Columns of the output for an input of ``c`` columns (after ``column``); the refusal of
        a multi-column field at several times."""
        count = time_count(self.times, self.scales)
        if c > 1 and count > 1:
            raise MeshError(f"attribute {self.attribute!r} has {c} columns (0..{c - 1}): pick one with column=N "
                            "(0 is the first, -1 the last) to smooth it at several times, or give one time "
                            "(times=T) to smooth every column")
        return count if count > 1 else c

    def plan(self, columns: dict[str, int]) -> dict[str, int]:
        """What this filter writes, given the input's attributes (see :meth:`o3dheat.pipelines.filters.Chain.check`).

        Examples
        --------
        >>> import o3dheat.pipelines.filters as flt
        >>> flt.get("heat_smooth", attribute="positions", column=2, scales=5).plan({"positions": 3})
        {'positions_smooth': 5}
        """
        c = need_attribute(columns, self.attribute)
        if self.column is not None:
            check_column(c, self.attribute, self.column)
            c = 1
        return {self.output or f"{self.attribute}_smooth": self._columns_out(c)}

    def __call__(self, geometry):
        """Smooth the attribute (see the class docstring).

        Parameters
        ----------
        geometry : Open3D TriangleMesh or PointCloud (legacy or tensor), (V, F) pair or mesh-like
            The input, holding ``attribute``; it is not modified.

        Returns
        -------
        open3d.t.geometry.TriangleMesh or open3d.t.geometry.PointCloud
            A copy of the input (tensor geometry) with ``output`` added: (n,) for one time, (n, T)
            for T times, (n, c) for c columns at one time.
        """
        site = Site(geometry, self.operators, step=self)
        f = site.attribute(self.attribute, self.column)
        count = time_count(self.times, self.scales)
        self._columns_out(f.shape[1] if f.ndim == 2 else 1)  # checked before the eigensolve
        if f.ndim == 2 and f.shape[1] == 1 and count > 1:  # one column: (n, T) like an (n,) field
            f = f[:, 0]
        K = smoother(site, self.method, self.k, self.variant, self.normalize, self.tol)
        if self.times or self.method == "spectral":
            t = times_of(K, self.times, self.scales, self.grid)
        else:  # the scales are defined by the spectrum
            t = times_of(kernel_of(site, self.k, self.variant, self.normalize), None, self.scales, self.grid)
        t = t if len(t) > 1 else float(t[0])
        g = K.smooth(site.to_surface(f), t)
        site.set(self.output or f"{self.attribute}_smooth", site.from_surface(g))
        return site.result()
