"""The ``critical_points`` filter: PL critical points of an attribute."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from o3dheat.errors import MeshError
from o3dheat.pipelines.site import (
    Operators,
    Site,
    check_column,
    checked,
    fraction,
    need_attribute,
    persistence,
)
from o3dheat.topology import Surface, critical_points, simplify_critical_points


@dataclass(frozen=True)
class CriticalPointsFilter:
    """Label the PL critical points of an attribute -> ``<attribute>_critical`` int8 per vertex:
    0 regular, 1 minimum, 2 saddle, 3 maximum.

    Parameters
    ----------
    attribute : str
        The field.
    column : int or None
        Which column of a multi-column attribute, (n, c) or (n, a, b...) flattened row-major like
        its PLY properties ``<attribute>_0 ..``: 0-based, negative counts from the end (-1 is the
        last). Needed when the attribute has several columns: without it the filter refuses,
        listing the columns (the rule of every filter and of ``o3dheat figure --column``).
    delta : float or None
        Keep only the critical points of the δ-simplification (persistence >= delta, units of
        the field, >= 0) and the essential ones; the others are labelled 0.
    keep_fraction : float or None
        Alternative to delta: the most persistent fraction of the pairs, in [0, 1].
    output : str or None
        Default "<attribute>_critical".
    operators : {"reconstruct", "robust"}
        For point clouds (only "reconstruct": critical points need a surface).

    Examples
    --------
    >>> import numpy as np, open3d as o3d, o3dheat.pipelines.filters as flt
    >>> m = flt.apply(o3d.t.geometry.TriangleMesh.create_sphere(1.0, 20), "scalar", kind="height")
    >>> np.bincount(flt.apply(m, "critical_points", attribute="height").vertex["height_critical"].numpy())
    array([760,   1,   0,   1])
    """

    attribute: str = "height"
    column: int | None = None
    delta: float | None = persistence()
    keep_fraction: float | None = fraction()
    output: str | None = None
    operators: Operators = "reconstruct"

    outputs = ("<attribute>_critical",)

    def __post_init__(self):
        checked(self)
        if self.delta is not None and self.keep_fraction is not None:
            raise MeshError("give delta or keep_fraction, not both")

    def plan(self, columns: dict[str, int]) -> dict[str, int]:
        """What this filter writes, given the input's attributes (see :meth:`o3dheat.pipelines.filters.Chain.check`).

        Examples
        --------
        >>> import o3dheat.pipelines.filters as flt
        >>> flt.get("critical_points", attribute="height").plan({"positions": 3, "height": 1})
        {'height_critical': 1}
        """
        check_column(need_attribute(columns, self.attribute), self.attribute, self.column)
        return {self.output or f"{self.attribute}_critical": 1}

    def __call__(self, geometry):
        """Label the critical points (see the class docstring).

        Parameters
        ----------
        geometry : Open3D TriangleMesh or PointCloud (legacy or tensor), (V, F) pair or mesh-like
            The input, holding ``attribute``; it is not modified.

        Returns
        -------
        open3d.t.geometry.TriangleMesh or open3d.t.geometry.PointCloud
            A copy of the input (tensor geometry) with ``output`` added: (n,) int8, 0 regular,
            1 minimum, 2 saddle, 3 maximum (on a point cloud: at the points nearest the critical
            vertices of its reconstructed surface).
        """
        site = Site(geometry, self.operators, step=self)
        f, V, F, g = site.scalar_on_surface(self.attribute, self.column)
        S = Surface((V, F))  # once for both (duplicate vertices welded once)
        kind = critical_points(S, g).kind
        if self.delta is not None or self.keep_fraction is not None:
            keep = simplify_critical_points(S, g, delta=self.delta, keep_fraction=self.keep_fraction)
            mask = np.zeros(len(kind), bool)
            mask[keep] = True
            if S.representative is not None:  # the copies of a welded vertex follow their first copy
                mask = mask[S.representative]
            kind[~mask] = 0
        (kind,) = site.labels_from_surface(kind != 0, kind)  # a cloud: at the nearest points
        site.set(self.output or f"{self.attribute}_critical", kind.astype(np.int8))
        return site.result()
