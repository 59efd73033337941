"""The ``tracks`` filter: how long each critical point of an attribute lives under its heat flow."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from o3dheat import topology
from o3dheat.errors import MeshError
from o3dheat.pipelines.site import (
    Method,
    Operators,
    Site,
    Variant,
    check_column,
    checked,
    eigenpairs,
    kernel_of,
    need_attribute,
    param,
    scale_count,
    smoother,
    time_list,
    tolerance,
)
from o3dheat.spectral.variants import mass_of

#: the codes of ``<attribute>_track_kind``, as ``critical_points``' labels (0 is regular)
KIND_CODES = {"minimum": topology.MINIMUM, "saddle": topology.SADDLE, "maximum": topology.MAXIMUM}


@dataclass(frozen=True)
class TracksFilter:
    """Follow the critical points of an attribute across the scales of its heat flow
    (:func:`o3dheat.track_critical_points <o3dheat.topology.tracking.track_critical_points>`) -> ``<attribute>_lifetime`` float64 per vertex, the
    time its track lives to, and ``<attribute>_track_kind`` int8 (0 regular, 1 minimum, 2 saddle,
    3 maximum: the labels of the ``critical_points`` filter).

    The tracked fields are ``Φ_t f`` at increasing times, the first ``t = 0``: the attribute itself
    (with either method). ``<attribute>_lifetime`` is, for each critical vertex of the attribute,
    the time of the last scale its track lives at; it is 0 at the other vertices (and for a
    critical point gone at the first time after 0: ``<attribute>_track_kind`` tells them apart).
    A critical point alive at the last time gets the last time (it lives at least that long: the
    largest value of the output), not ``inf``: the values are finite, so that the other filters
    (``colorize``; filters refuse infinite attributes) and every file format take them, and
    thresholding at a time ``τ`` of the grid keeps exactly the features of
    :meth:`o3dheat.Tracks.features <o3dheat.topology.tracking.Tracks.features>` at ``τ``. Typically an extremum and a saddle
    that cancel get the same lifetime, smaller than the surviving extrema's.

    Parameters
    ----------
    attribute : str
        The field.
    column : int or None
        Which column of a multi-column attribute, (n, c) or (n, a, b...) flattened row-major like
        its PLY properties ``<attribute>_0 ..``: 0-based, negative counts from the end (-1 is the
        last). Needed when the attribute has several columns: without it the filter refuses,
        listing the columns (the rule of every filter and of ``o3dheat figure --column``).
    times : list of float or None
        Times (paper convention ``exp(−λ t / 2)``), strictly increasing, each >= 0; ``t = 0``
        is put first when they do not begin with it. Default (None): ``t = 0`` and ``scales``
        log-spaced times from the paper's first scale ``(1/10) / λ_k`` to ``2 ln(100) / λ_2``
        (the first non-constant mode damped to 1%: the field nearly constant), ``λ_k`` and
        ``λ_2`` of the spectrum of ``k`` eigenpairs.
    scales : int
        Number of log-spaced times after ``t = 0`` when ``times`` is not given (1 to 100000;
        default 40: a step of about 1.24x in time for 100 eigenpairs on a sphere, fine enough for the
        matching of :func:`o3dheat.track_critical_points <o3dheat.topology.tracking.track_critical_points>`).
    variant : str
        The kernel, a key of :data:`o3dheat.spectral.variants.VARIANTS` (each on the spectrum of its own mass;
        "weighted" is the paper's).
    k : int
        Eigenpairs (>= 1; capped at what the mesh has, with a warning): with "exact" they only
        place the default times (give ``times`` to skip the eigensolve); with "spectral" they are
        the kernel's.
    method : str
        One of :data:`o3dheat.spectral.heatflow.METHODS`. "exact" (the default, unlike ``heat_smooth``):
        the full kernel (:class:`o3dheat.HeatFlow <o3dheat.spectral.heatflow.HeatFlow>`), to ``tol``. Tracking needs many scales, from
        small times where the truncated kernel is ``k``'s band-limited projection rather than
        ``Φ_t f`` (its critical points are the truncation's), and the exact flow at 40 times
        costs less than the eigensolve that places them (0.2 s against 1.4 s for 100 eigenpairs
        on a sphere of 3,122 vertices). "spectral": the truncated kernel on ``k`` eigenpairs
        (the first field is still the attribute itself).
    tol : float
        Relative W-norm error of the exact method, in (0, 1).
    radius : float or None
        Largest distance (mesh units, > 0) a saddle moves between two scales; default 10 mean
        edge lengths (see :func:`o3dheat.track_critical_points <o3dheat.topology.tracking.track_critical_points>`).
    operators : {"reconstruct", "robust"}
        For point clouds (only "reconstruct": critical points need a surface); the outputs go to
        the points nearest the critical vertices of the reconstructed surface.

    Examples
    --------
    A tilted height and a Gaussian bump: the shallow maximum at the pole and a saddle cancel; the
    bump's maximum and the minimum live to the last time.

    >>> import numpy as np, open3d as o3d, o3dheat.pipelines.filters as flt
    >>> m = o3d.t.geometry.TriangleMesh.create_sphere(1.0, 40)
    >>> V = m.vertex.positions.numpy()
    >>> m.vertex["f"] = o3d.core.Tensor(0.2 * V[:, 2] + np.exp(-((V[:, 0] - 1) ** 2 + V[:, 1] ** 2) / 0.05))
    >>> out = flt.apply(m, "tracks", attribute="f", times=np.geomspace(1e-3, 1.0, 12).tolist())
    >>> life, kind = out.vertex["f_lifetime"].numpy(), out.vertex["f_track_kind"].numpy()
    >>> [(int(kind[v]), round(float(life[v]), 3)) for v in np.flatnonzero(kind)]
    [(3, 0.043), (1, 1.0), (2, 0.043), (3, 1.0)]
    """

    attribute: str = "height"
    column: int | None = None
    times: tuple[float, ...] | None = time_list()
    scales: int = scale_count(40)
    variant: Variant = "weighted"
    k: int = eigenpairs()
    method: Method = "exact"
    tol: float = tolerance()
    radius: float | None = param(None, gt=0)
    operators: Operators = "reconstruct"

    outputs = ("<attribute>_lifetime", "<attribute>_track_kind")

    def __post_init__(self):
        checked(self)
        mass_of(self.variant)  # an unknown variant: MeshError listing o3dheat.spectral.variants.VARIANTS
        if self.times and np.any(np.diff(self.times) <= 0):
            raise MeshError(f"tracks.times must be strictly increasing, got {self.times!r}")

    def plan(self, columns: dict[str, int]) -> dict[str, int]:
        """What this filter writes, given the input's attributes (see :meth:`o3dheat.pipelines.filters.Chain.check`).

        Examples
        --------
        >>> import o3dheat.pipelines.filters as flt
        >>> flt.get("tracks", attribute="height").plan({"positions": 3, "height": 1})
        {'height_lifetime': 1, 'height_track_kind': 1}
        """
        check_column(need_attribute(columns, self.attribute), self.attribute, self.column)
        return {f"{self.attribute}_lifetime": 1, f"{self.attribute}_track_kind": 1}

    def grid(self, site: Site) -> np.ndarray:
        """The times tracked on ``site`` (a :class:`~o3dheat.pipelines.site.Site`): ``t = 0`` first,
        then ``times`` or the default log grid (see the class docstring).

        Examples
        --------
        >>> import open3d as o3d
        >>> from o3dheat.pipelines.site import Site
        >>> from o3dheat_filters.tracks import TracksFilter
        >>> site = Site(o3d.t.geometry.TriangleMesh.create_sphere(1.0, 8))
        >>> TracksFilter(times=(0.1, 0.2)).grid(site).tolist()
        [0.0, 0.1, 0.2]
        >>> t = TracksFilter(scales=5, k=20).grid(site)
        >>> len(t), float(t[0]), bool(t[1] > 0)
        (6, 0.0, True)
        """
        if self.times:
            t = np.asarray(self.times, dtype=np.float64)
        else:
            K = kernel_of(site, self.k, self.variant)
            lo = float(K.scales(10)[0])  # (1/10)/λ_k: the paper's first scale
            hi = float(K.scales(2, grid="log")[-1])  # 2 ln(100)/λ_2 (at least 10/λ_k > lo)
            t = np.geomspace(lo, hi, self.scales)
        return t if t[0] == 0 else np.r_[0.0, t]

    def __call__(self, geometry):
        """Track the critical points (see the class docstring).

        Parameters
        ----------
        geometry : Open3D TriangleMesh or PointCloud (legacy or tensor), (V, F) pair or mesh-like
            The input, holding ``attribute``; it is not modified.

        Returns
        -------
        open3d.t.geometry.TriangleMesh or open3d.t.geometry.PointCloud
            A copy of the input (tensor geometry) with ``<attribute>_lifetime`` (n,) float64 and
            ``<attribute>_track_kind`` (n,) int8 added.
        """
        site = Site(geometry, self.operators, step=self)
        f, V, F, g = site.scalar_on_surface(self.attribute, self.column)
        S = topology.Surface((V, F))  # welded once, for the tracking and the outputs
        t = self.grid(site)
        phi = smoother(site, self.method, self.k, self.variant, tol=self.tol)
        fields = np.empty((len(g), len(t)))
        fields[:, 0] = g  # t = 0: the attribute itself (not its spectral projection)
        if len(t) > 1:
            fields[:, 1:] = np.asarray(phi.smooth(g, t[1:])).reshape(len(g), -1)
        tr = topology.track_critical_points(S, fields, t, radius=self.radius)
        start = tr.first == 0
        verts = tr.vertex[start, 0]
        life = np.zeros(len(g))
        kind = np.zeros(len(g), np.int8)
        life[verts] = t[tr.last[start]]
        kind[verts] = [KIND_CODES[k] for k in tr.kind[start]]
        if S.representative is not None:  # the copies of a welded vertex follow their first copy
            life, kind = life[S.representative], kind[S.representative]
        life, kind = site.labels_from_surface(kind != 0, life, kind)  # a cloud: at the nearest points
        site.set(f"{self.attribute}_lifetime", life)
        site.set(f"{self.attribute}_track_kind", kind)
        return site.result()
