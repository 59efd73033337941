"""The filter SDK: :class:`Site` (a filter's copy of its input: attributes, surface, spectrum), parameter types, kernels.

Entry points: :class:`Site`, :func:`checked`; parameter types (:data:`Variant`, :data:`Method`, ...)
and bounds (:func:`eigenpairs`, :func:`time_list`, ...); :func:`kernel_of`, :func:`flow_of`,
:func:`smoother`, :func:`times_of`; for a ``plan``, :func:`param`, :func:`check_column`,
:func:`need_attribute`. The built-in filters (``o3dheat_filters``) are written with it.

Notes
-----
Point clouds: ``operators="reconstruct"`` builds a surface through the points
(:func:`o3dheat.geometry.points.reconstruct`, Poisson), moves input fields to its vertices
(nearest point), computes there and brings results back to the points by barycentric
interpolation at the closest surface point; ``operators="robust"`` uses robust-laplacian's
point-cloud Laplacian and lumped mass on the points (no surface, so no critical points), when that
package is installed (``pip install robust-laplacian``). Meshes: the filter works on the mesh.
"""

from __future__ import annotations

import logging
import typing
from typing import Annotated, Literal

import numpy as np

from o3dheat import checks
from o3dheat.errors import MeshError
from o3dheat.geometry import as_arrays, interpolation
from o3dheat.geometry import mesh as meshes
from o3dheat.spectral import HeatFlow, HeatKernel, Spectrum, heatflow, variants
from o3dheat.typing import MeshLike

from . import _clouds as clouds
from .filters import (
    OneOf,
    attribute_columns,
    check_column,
    check_parameters,
    check_step,
    check_writable,
    need_attribute,
    one_column,
    param,
    shared_spectrum,
)

if typing.TYPE_CHECKING:  # annotations only: Open3D is imported where it is used (it takes seconds)
    import open3d as o3d

__all__ = ["Site", "checked", "OPERATORS", "MAX_SCALES", "Variant", "Grid", "HksForm", "Normalization", "Operators",
           "Method", "eigenpairs", "scale_count", "time_list", "tolerance", "persistence", "fraction", "kernel_of",
           "flow_of", "smoother", "time_count", "times_of", "param", "check_column", "need_attribute"]

log = logging.getLogger("o3dheat")

#: how point clouds get operators (``operators=`` of the filters)
OPERATORS = ("reconstruct", "robust")
#: parameter types shared by the filters, from the kernel module's single definitions; the variants
#: are read when a value is checked, so that a variant added to o3dheat.spectral.variants.VARIANTS (even at
#: run time) is accepted by every filter at once
Variant = Annotated[str, OneOf(lambda: variants.VARIANTS)]
Grid = Literal[variants.GRIDS]
HksForm = Literal[variants.HKS_FORMS]
Normalization = Literal[variants.NORMALIZATIONS]
Operators = Literal[OPERATORS]
Method = Literal[heatflow.METHODS]

#: the bounds of the parameters several filters share (:func:`param`), declared once:
#: ``k: int = eigenpairs()`` ...
MAX_SCALES = 100_000  # as o3dheat.spectral.kernel's scales


def eigenpairs(default: int = 100) -> typing.Any:
    """``k``: eigenpairs, at least 1 (more than the mesh has are capped, with a warning).

    Examples
    --------
    >>> from o3dheat.pipelines.site import eigenpairs
    >>> eigenpairs().metadata["o3dheat.limits"].ge
    1
    """
    return param(default, ge=1)


def scale_count(default: int = 10) -> typing.Any:
    """``scales``: how many times of a grid, 1 to :data:`MAX_SCALES`.

    Examples
    --------
    >>> from o3dheat.pipelines.site import scale_count
    >>> str(scale_count().metadata["o3dheat.limits"])
    'in [1, 100000]'
    """
    return param(default, ge=1, le=MAX_SCALES)


def time_list() -> typing.Any:
    """``times``: None (the default grid) or at least one time, each >= 0 (finite: a float).

    Examples
    --------
    >>> from o3dheat.pipelines.site import time_list
    >>> str(time_list().metadata["o3dheat.limits"])
    '>= 0, at least 1 value'
    """
    return param(None, ge=0, min_len=1)


def tolerance(default: float = 1e-8) -> typing.Any:
    """``tol``: a relative tolerance in (0, 1) (:func:`o3dheat.checks.tolerance`).

    Examples
    --------
    >>> from o3dheat.pipelines.site import tolerance
    >>> str(tolerance().metadata["o3dheat.limits"])
    'in (0, 1)'
    """
    return param(default, gt=0, lt=1)


def persistence() -> typing.Any:
    """``delta``: a persistence threshold in the field's units, >= 0 (None: not given).

    Examples
    --------
    >>> from o3dheat.pipelines.site import persistence
    >>> str(persistence().metadata["o3dheat.limits"])
    '>= 0'
    """
    return param(None, ge=0)


def fraction() -> typing.Any:
    """``keep_fraction``: a fraction in [0, 1] (None: not given), as
    :func:`o3dheat.simplify_critical_points <o3dheat.topology.diagrams.simplify_critical_points>` takes it.

    Examples
    --------
    >>> from o3dheat.pipelines.site import fraction
    >>> str(fraction().metadata["o3dheat.limits"])
    'in [0, 1]'
    """
    return param(None, ge=0, le=1)


def checked(step: typing.Any) -> None:
    """At construction (``__post_init__``): every parameter of a built-in filter checked against its
    type and bounds (:func:`o3dheat.pipelines.filters.check_parameters`) and stored converted, so that a
    filter made directly is refused as one made by name, before any work.

    Examples
    --------
    >>> from o3dheat_filters.hks import Hks
    >>> Hks(k=20.0)
    Traceback (most recent call last):
    ...
    o3dheat.errors.MeshError: hks.k must be an integer, got 20.0
    """
    for name, value in check_parameters(step).items():
        if value is not getattr(step, name):
            object.__setattr__(step, name, value)  # frozen: the documented way in __post_init__


class Site:
    """A copy of the input geometry that a filter reads and writes.

    Parameters
    ----------
    geometry : Open3D TriangleMesh or PointCloud (legacy or tensor), (V, F) pair or mesh-like
        A mesh-like (:func:`o3dheat.geometry.mesh.mesh_of`: a Repaired, a Resampled) stands for its mesh.
    operators : str
        One of :data:`OPERATORS`: how a point cloud gets its operators.
    step : filter or None
        The filter about to run: its plan and outputs are checked on the geometry's attributes
        now, before any work (:func:`o3dheat.pipelines.filters.check_step`, as :meth:`~o3dheat.pipelines.filters.Chain.check`
        does for a chain), so that a filter called directly or by
        :func:`~o3dheat.pipelines.filters.apply` refuses what it cannot write before computing it.

    Examples
    --------
    >>> import open3d as o3d
    >>> from o3dheat.pipelines.site import Site
    >>> site = Site(o3d.t.geometry.TriangleMesh.create_sphere(1.0, 8))
    >>> site.n, site.is_mesh
    (114, True)
    """

    def __init__(self, geometry: MeshLike | o3d.t.geometry.PointCloud | o3d.geometry.PointCloud,
                 operators: str = "reconstruct", step: typing.Any = None):
        import open3d as o3d

        self.o3d = o3d
        if operators not in OPERATORS:
            raise MeshError(f"unknown operators {operators!r}: use one of {OPERATORS}")
        self.operators = operators
        geometry = meshes.mesh_of(geometry)  # a Repaired, a Resampled, any mesh-like: the mesh it holds
        if isinstance(geometry, (tuple, list)) and len(geometry) == 2:  # (V, F) arrays
            V, F = as_arrays(geometry)
            geometry = o3d.t.geometry.TriangleMesh()
            geometry.vertex.positions = o3d.core.Tensor(V)
            geometry.triangle.indices = o3d.core.Tensor(F)
        if isinstance(geometry, o3d.geometry.TriangleMesh):
            geometry = o3d.t.geometry.TriangleMesh.from_legacy(geometry)
        elif isinstance(geometry, o3d.geometry.PointCloud):
            geometry = o3d.t.geometry.PointCloud.from_legacy(geometry)
        if isinstance(geometry, o3d.t.geometry.TriangleMesh):
            self.is_mesh = True
            self.out = geometry.clone()
            self.attrs = self.out.vertex
            if "positions" not in self.attrs or "indices" not in self.out.triangle:
                raise MeshError("the mesh has no vertices or no triangles")
        elif isinstance(geometry, o3d.t.geometry.PointCloud):
            self.is_mesh = False
            self.out = geometry.clone()
            self.attrs = self.out.point
            if "positions" not in self.attrs:
                raise MeshError("the point cloud has no points")
        else:
            raise MeshError("a filter takes an Open3D TriangleMesh or PointCloud, a (V, F) pair or a mesh-like "
                            f"(an object with a .mesh, e.g. a Repaired or a Resampled), got {type(geometry).__name__}")
        if step is not None:
            check_step(step, attribute_columns(self.out))
        self.P = self.attrs.positions.numpy().astype(np.float64)
        self.n = len(self.P)
        self._surface = None

    # ------------------------------------------------------------------------ attributes
    def names(self) -> list[str]:
        """The vertex attributes' names.

        Examples
        --------
        >>> import open3d as o3d
        >>> from o3dheat.pipelines.site import Site
        >>> Site(o3d.t.geometry.TriangleMesh.create_sphere(1.0, 8)).names()
        ['positions']
        """
        return [k for k in self.attrs]

    def attribute(self, name: str, column: int | None = None) -> np.ndarray:
        """A vertex attribute as float64 (n,) or (n, c) (trailing axes flattened row-major);
        ``column`` picks one column (:func:`o3dheat.pipelines.filters.one_column`).

        Examples
        --------
        >>> import numpy as np, open3d as o3d
        >>> from o3dheat.pipelines.site import Site
        >>> site = Site(o3d.t.geometry.TriangleMesh.create_sphere(1.0, 8))
        >>> site.attribute("positions").shape, site.attribute("positions", column=2).shape
        ((114, 3), (114,))
        """
        need_attribute(dict.fromkeys(self.names()), name)
        a = self.attrs[name].numpy()
        if len(a) != self.n:
            raise MeshError(f"attribute {name!r} has {len(a)} rows for {self.n} vertices")
        a = a.astype(np.float64).reshape(self.n, -1) if a.ndim > 1 else a.astype(np.float64)
        if column is not None:
            a = one_column(a, name, column)
        return checks.field(a, self.n, f"attribute {name!r}")  # names the count and the first bad vertex

    def scalar(self, name: str, column: int | None = None) -> np.ndarray:
        """One column of an attribute, (n,), by the filters' rule (:func:`o3dheat.pipelines.filters.one_column`):
        a multi-column attribute without ``column`` is refused, listing its columns.

        Examples
        --------
        >>> import numpy as np, open3d as o3d
        >>> from o3dheat.pipelines.site import Site
        >>> site = Site(o3d.t.geometry.TriangleMesh.create_sphere(1.0, 8))
        >>> site.scalar("positions", column=-1).shape
        (114,)
        """
        a = self.attribute(name, column)
        return a if column is not None else one_column(a, name)

    def scalar_on_surface(self, name: str, column: int | None = None) -> tuple:
        """(f on the input vertices, V, F of the surface, f on the surface vertices).

        Examples
        --------
        >>> import numpy as np, open3d as o3d
        >>> from o3dheat.pipelines.site import Site
        >>> site = Site(o3d.t.geometry.TriangleMesh.create_sphere(1.0, 8))
        >>> f, V, F, g = site.scalar_on_surface("positions", column=2)
        >>> V.shape, F.shape, bool(np.array_equal(f, g))    # a mesh is its own surface
        ((114, 3), (224, 3), True)
        """
        f = self.scalar(name, column)
        V, F = self.surface()
        return f, V, F, self.to_surface(f)

    def set(self, name: str, values: np.ndarray) -> None:
        """Write a vertex attribute on the copy (one row per input vertex; never "positions").

        Examples
        --------
        >>> import numpy as np, open3d as o3d
        >>> from o3dheat.pipelines.site import Site
        >>> site = Site(o3d.t.geometry.TriangleMesh.create_sphere(1.0, 8))
        >>> site.set("f", np.zeros(site.n))
        >>> sorted(site.names())
        ['f', 'positions']
        """
        values = np.ascontiguousarray(values)
        if len(values) != self.n:  # pragma: no cover - a filter bug
            raise AssertionError(f"{name}: {len(values)} rows for {self.n} vertices")
        check_writable(name, values.shape[1:], attribute_columns(self.out))
        self.attrs[name] = self.o3d.core.Tensor(values)

    def result(self) -> typing.Any:
        """The copy with the attributes written: what the filter returns (the input is unchanged).

        Examples
        --------
        >>> import numpy as np, open3d as o3d
        >>> from o3dheat.pipelines.site import Site
        >>> mesh = o3d.t.geometry.TriangleMesh.create_sphere(1.0, 8)
        >>> site = Site(mesh)
        >>> site.set("f", np.zeros(site.n))
        >>> "f" in site.result().vertex, "f" in mesh.vertex
        (True, False)
        """
        return self.out

    # --------------------------------------------------------------- surface and spectrum
    def surface(self) -> tuple[np.ndarray, np.ndarray]:
        """(V, F) the operators are built on: the mesh, or the reconstruction of the points.

        Examples
        --------
        >>> import numpy as np, open3d as o3d
        >>> from o3dheat.pipelines.site import Site
        >>> site = Site(o3d.t.geometry.TriangleMesh.create_sphere(1.0, 8))
        >>> [a.shape for a in site.surface()]
        [(114, 3), (224, 3)]
        """
        if self._surface is None:
            if self.is_mesh:
                F = self.out.triangle.indices.numpy().astype(np.int64)
                self._surface = (self.P, F)
            elif self.operators == "robust":
                raise MeshError("this filter needs a surface (faces): use operators='reconstruct' for "
                                "point clouds")
            else:
                self._surface = clouds.reconstruction(self)
        return self._surface

    def to_surface(self, f: np.ndarray) -> np.ndarray:
        """Per-input-vertex values -> per-surface-vertex values.

        Examples
        --------
        >>> import numpy as np, open3d as o3d
        >>> from o3dheat.pipelines.site import Site
        >>> site = Site(o3d.t.geometry.TriangleMesh.create_sphere(1.0, 8))
        >>> site.to_surface(np.ones(site.n)).shape    # a mesh: the same values
        (114,)
        """
        if self.is_mesh or self.operators == "robust":
            return f
        return interpolation.nearest(f, self.P, self.surface()[0])

    def from_surface(self, g: np.ndarray) -> np.ndarray:
        """Per-surface-vertex values -> per-input-vertex values.

        Examples
        --------
        >>> import numpy as np, open3d as o3d
        >>> from o3dheat.pipelines.site import Site
        >>> site = Site(o3d.t.geometry.TriangleMesh.create_sphere(1.0, 8))
        >>> site.from_surface(np.ones((site.n, 2))).shape
        (114, 2)
        """
        if self.is_mesh or self.operators == "robust":
            return g
        V, F = self.surface()
        g = np.asarray(g)
        flat = g.reshape(len(V), -1)
        out = interpolation.transfer(flat, (V, F), self.P)
        return out.reshape((self.n,) + g.shape[1:])

    def labels_from_surface(self, where: np.ndarray, *values: np.ndarray) -> tuple[np.ndarray, ...]:
        """Values that live at a few surface vertices (``where``, a mask: critical points, their
        lifetimes) moved to the input points nearest those vertices, 0 elsewhere (a mesh: as given).

        Examples
        --------
        >>> import numpy as np, open3d as o3d
        >>> from o3dheat.pipelines.site import Site
        >>> site = Site(o3d.t.geometry.TriangleMesh.create_sphere(1.0, 8))
        >>> kind = np.zeros(site.n, np.int8); kind[3] = 1
        >>> [v.nonzero()[0].tolist() for v in site.labels_from_surface(kind != 0, kind)]
        [[3]]
        """
        if self.is_mesh:
            return values
        crit = np.flatnonzero(where)
        at = interpolation.nearest(np.arange(self.n), self.P, self.surface()[0][crit])
        out = tuple(np.zeros(self.n, np.asarray(v).dtype) for v in values)
        for o, v in zip(out, values, strict=True):
            o[at] = np.asarray(v)[crit]
        return out

    def spectrum(self, k: int = 100, mass: str = "consistent", cache: typing.Any = None) -> Spectrum:
        """The spectrum of the surface with the mass ``mass`` (:data:`o3dheat.spectral.fem.MASS_KINDS`),
        shared by the filters (:func:`o3dheat.pipelines.filters.shared_spectrum`); robust-laplacian's for
        point clouds with ``operators="robust"``. A ``k`` larger than the surface allows (its
        vertices; the points less 2 for robust-laplacian's) is capped, with a warning on the
        ``o3dheat`` logger naming the ``k`` asked for and the ``k`` used.

        Examples
        --------
        >>> import numpy as np, open3d as o3d
        >>> from o3dheat.pipelines.site import Site
        >>> site = Site(o3d.t.geometry.TriangleMesh.create_sphere(1.0, 8))
        >>> s = site.spectrum(k=5, mass="lumped")
        >>> s.k, s.mass_kind
        (5, 'lumped')
        """
        if not self.is_mesh and self.operators == "robust":
            s = clouds.robust_spectrum(self.P, k)
        else:
            V, F = self.surface()
            s = shared_spectrum(V, F, k=k, mass=mass, cache=cache)
        if s.k < k:
            log.warning("k=%d eigenpairs asked for, but this surface allows %d: using k=%d (ask for k <= %d "
                        "to silence this)", k, s.k, s.k, s.k)
        return s


def kernel_of(site: Site, k: int, variant: str = "weighted", normalize: str | None = None) -> HeatKernel:
    """The heat kernel ``variant`` (:data:`o3dheat.spectral.variants.VARIANTS`) on the site's own spectrum
    of that variant's mass; point clouds with ``operators="robust"`` have robust-laplacian's
    mass only ("weighted").

    Examples
    --------
    >>> import open3d as o3d
    >>> from o3dheat.pipelines.site import Site, kernel_of
    >>> K = kernel_of(Site(o3d.t.geometry.TriangleMesh.create_sphere(1.0, 8)), 5, "voronoi")
    >>> K.variant, K.spectrum.mass_kind
    ('voronoi', 'voronoi')
    """
    if not site.is_mesh and site.operators == "robust" and variant != "weighted":
        raise MeshError(f"operators='robust' comes with robust-laplacian's own mass: use variant='weighted', "
                        f"or operators='reconstruct' for the {variant!r} kernel")
    mass = variants.mass_of(variant)  # an unknown variant: MeshError listing them
    return HeatKernel(site.spectrum(k=k, mass=mass), variant=variant, normalize=normalize)


def flow_of(site: Site, variant: str = "weighted", normalize: str | None = None, tol: float = 1e-8) -> HeatFlow:
    """The full heat kernel ``variant`` (:class:`o3dheat.HeatFlow <o3dheat.spectral.heatflow.HeatFlow>`) of the site's surface (its
    operators and factors cached for the chain), to ``tol``; robust-laplacian's operators for point
    clouds with ``operators="robust"`` ("weighted" only).

    Examples
    --------
    >>> import open3d as o3d
    >>> from o3dheat.pipelines.site import Site, flow_of
    >>> flow = flow_of(Site(o3d.t.geometry.TriangleMesh.create_sphere(1.0, 8)), "lumped")
    >>> flow.variant, flow.n
    ('lumped', 114)
    """
    variants.mass_of(variant)  # an unknown variant: MeshError listing them
    if not site.is_mesh and site.operators == "robust":
        if variant != "weighted":
            raise MeshError(f"operators='robust' comes with robust-laplacian's own mass: use variant='weighted', "
                            f"or operators='reconstruct' for the {variant!r} kernel")
        L, M = clouds.robust_operators(site.P)
        return HeatFlow.from_operators(L, M, normalize=normalize, tol=tol)
    return HeatFlow(site.surface(), variant=variant, normalize=normalize, tol=tol)


def smoother(site: Site, method: str, k: int, variant: str = "weighted", normalize: str | None = None,
             tol: float = 1e-8) -> HeatKernel | HeatFlow:
    """What computes ``Φ_t`` for a filter: the spectral kernel (:func:`kernel_of`) or the full one
    (:func:`flow_of`, to ``tol``), by ``method`` (:data:`o3dheat.spectral.heatflow.METHODS`); either has
    ``smooth(f, t)``.

    Examples
    --------
    >>> import open3d as o3d
    >>> from o3dheat.pipelines.site import Site, smoother
    >>> site = Site(o3d.t.geometry.TriangleMesh.create_sphere(1.0, 8))
    >>> type(smoother(site, "spectral", 5)).__name__, type(smoother(site, "exact", 5)).__name__
    ('HeatKernel', 'HeatFlow')
    """
    if method not in heatflow.METHODS:
        raise MeshError(f"unknown method {method!r}: use one of {', '.join(heatflow.METHODS)}")
    return kernel_of(site, k, variant, normalize) if method == "spectral" else flow_of(site, variant, normalize, tol)


def time_count(times: typing.Sequence[float] | None, scales: int) -> int:
    """How many times :func:`times_of` gives: the columns of a filter's multi-scale output.

    Examples
    --------
    >>> from o3dheat.pipelines.site import time_count
    >>> time_count(None, 10), time_count((0.1, 0.2), 10)
    (10, 2)
    """
    return len(times) if times else scales


def times_of(kernel: HeatKernel, times: typing.Sequence[float] | None, scales: int, grid: str = "paper") -> np.ndarray:
    """Explicit times, or ``scales`` times of the kernel's ``grid``.

    Examples
    --------
    >>> import open3d as o3d
    >>> from o3dheat.pipelines.site import Site, kernel_of, times_of
    >>> K = kernel_of(Site(o3d.t.geometry.TriangleMesh.create_sphere(1.0, 8)), 5)
    >>> times_of(K, (0.1, 0.2), 3).tolist(), times_of(K, None, 3).shape
    ([0.1, 0.2], (3,))
    """
    if times:
        return np.asarray(times, dtype=np.float64)
    return kernel.scales(scales, grid=grid)
