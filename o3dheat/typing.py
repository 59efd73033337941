"""Type aliases of o3dheat's public signatures: what may be passed as a mesh, a field, times, a path.

Entry points: :data:`MeshLike`, :data:`FieldLike`, :data:`TimesLike`, :data:`PathLike`,
:class:`HasMesh`. They document the conventions of every public function in one place (a type
checker reads them too); they are checked at run time by the functions themselves, not here.

Examples
--------
>>> import numpy as np
>>> from o3dheat.typing import FieldLike, MeshLike
>>> def mean_height(mesh: MeshLike, field: FieldLike) -> float:
...     return float(np.mean(field))
>>> mean_height((np.eye(3), np.array([[0, 1, 2]])), [0.0, 1.0, 2.0])
1.0
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any, Protocol, Union, runtime_checkable

from numpy.typing import ArrayLike

if TYPE_CHECKING:  # Open3D's import takes seconds: the aliases name its classes without importing it
    import open3d

__all__ = ["MeshLike", "FieldLike", "TimesLike", "PathLike", "HasMesh"]


@runtime_checkable
class HasMesh(Protocol):
    """A mesh-like object: anything with a ``mesh`` attribute holding a :data:`MeshLike`
    (:class:`o3dheat.Repaired <o3dheat.geometry.repairs.Repaired>`, :class:`o3dheat.geometry.sampling.Resampled`, or one of yours;
    followed by :func:`o3dheat.geometry.mesh.mesh_of`).

    Examples
    --------
    >>> import numpy as np, o3dheat
    >>> from o3dheat.typing import HasMesh
    >>> isinstance(o3dheat.repair((np.eye(3), np.array([[0, 1, 2]]))), HasMesh)
    True
    """

    mesh: Any


#: a triangle mesh: Open3D's tensor or legacy ``TriangleMesh``, a ``(V, F)`` pair of arrays
#: (``V`` ``(n, 3)`` real, ``F`` ``(m, 3)`` 0-based integer), or a :class:`HasMesh` wrapper
MeshLike = Union["open3d.t.geometry.TriangleMesh", "open3d.geometry.TriangleMesh", tuple[ArrayLike, ArrayLike], HasMesh]  # noqa: UP007 - forward references

#: a field on the vertices: ``(n,)`` or ``(n, c)`` real values, one row per input vertex
FieldLike = ArrayLike

#: diffusion times (dimensionless, ``exp(-λ t / 2)`` convention): one non-negative number or a
#: sequence of them
TimesLike = float | Sequence[float] | ArrayLike

#: a file system path
PathLike = str | os.PathLike
