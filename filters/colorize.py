"""The ``colorize`` filter: vertex colours from an attribute."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from o3dheat.errors import MeshError
from o3dheat.pipelines.site import (
    Site,
    check_column,
    checked,
    need_attribute,
    param,
)


def _colormap(name):
    # here, not at the top: importing matplotlib costs ~0.25 s, which `import o3dheat` avoids
    from matplotlib import colormaps

    if name not in colormaps:
        raise MeshError(f"unknown colormap {name!r} (matplotlib names: viridis, coolwarm, ...)")
    return colormaps[name]


@dataclass(frozen=True)
class Colorize:
    """Colour the vertices by one column of an attribute, with a matplotlib colormap.

    The only filter that writes colours (``colors``, float32 in [0, 1]).

    Parameters
    ----------
    attribute : str
        The field.
    column : int or None
        Which column of a multi-column attribute, (n, c) or (n, a, b...) flattened row-major like
        its PLY properties ``<attribute>_0 ..``: 0-based, negative counts from the end (-1 is the
        last). Needed when the attribute has several columns: without it the filter refuses,
        listing the columns (the rule of every filter and of ``o3dheat figure --column``).
    colormap : str
        Any matplotlib colormap name ("coolwarm", "viridis", ...).
    range : list of 2 float or None
        Values mapped to the two ends; default the 2nd and 98th percentiles (robust to outliers).
    output : str
        The colour attribute.

    Examples
    --------
    >>> import open3d as o3d, o3dheat.pipelines.filters as flt
    >>> m = flt.apply(o3d.t.geometry.TriangleMesh.create_sphere(1.0, 10), "scalar", kind="height")
    >>> flt.apply(m, "colorize", attribute="height").vertex["colors"].shape
    SizeVector[182, 3]
    >>> m = flt.apply(m, "hks", k=20, scales=4)  # (n, 4): pick a column
    >>> flt.apply(m, "colorize", attribute="hks", column=-1).vertex["colors"].shape
    SizeVector[182, 3]
    """

    attribute: str = "height"
    column: int | None = None
    colormap: str = "coolwarm"
    range: tuple[float, ...] | None = param(None, min_len=2, max_len=2)
    output: str = "colors"

    outputs = ("colors",)

    def __post_init__(self):
        checked(self)
        if self.range is not None and not self.range[0] < self.range[1]:
            raise MeshError(f"range must be two increasing numbers, got {self.range}")

    def plan(self, columns: dict[str, int]) -> dict[str, int]:
        """What this filter writes, given the input's attributes (see :meth:`o3dheat.pipelines.filters.Chain.check`).

        Examples
        --------
        >>> import o3dheat.pipelines.filters as flt
        >>> flt.get("colorize", attribute="hks", column=-1).plan({"positions": 3, "hks": 10})
        {'colors': 3}
        """
        _colormap(self.colormap)
        check_column(need_attribute(columns, self.attribute), self.attribute, self.column)
        return {self.output: 3}

    def __call__(self, geometry):
        """Colour the vertices (see the class docstring).

        Parameters
        ----------
        geometry : Open3D TriangleMesh or PointCloud (legacy or tensor), (V, F) pair or mesh-like
            The input, holding ``attribute``; it is not modified.

        Returns
        -------
        open3d.t.geometry.TriangleMesh or open3d.t.geometry.PointCloud
            A copy of the input (tensor geometry) with the colour attribute ``output`` added: (n, 3) float32 in [0, 1].
        """
        colormap = _colormap(self.colormap)
        site = Site(geometry, step=self)
        f = site.scalar(self.attribute, self.column)
        lo, hi = self.range if self.range is not None else np.percentile(f, [2, 98])
        s = np.clip((f - lo) / (hi - lo), 0, 1) if hi > lo else np.full(f.shape, 0.5)
        rgb = colormap(s)[:, :3].astype(np.float32)
        site.set(self.output, rgb)
        return site.result()
