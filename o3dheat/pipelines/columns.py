"""Vertex attributes and their columns: which column a filter reads, what it may write, its plan checked.

Entry points: :func:`one_column` and :func:`check_column` (the one rule for picking a column),
:func:`attribute_columns` (a geometry's attributes and their column counts), :func:`need_attribute`,
:func:`check_writable` (the one check of an output's name and shape), :func:`check_step` (a
filter's ``plan`` before its work). All reachable from :mod:`o3dheat.pipelines.filters`.
"""

from __future__ import annotations

import re
import typing

import numpy as np

from o3dheat.errors import MeshError
from o3dheat.typing import FieldLike

__all__ = ["one_column", "check_column", "attribute_columns", "need_attribute", "check_writable", "check_step",
           "PROTECTED", "SHAPED", "PLY_RESERVED"]


def one_column(values: FieldLike, name: str, column: int | None = None, option: str = "column=") -> np.ndarray:
    """One column of a vertex attribute, by the rule every filter and command follows.

    A one-column attribute, (n,) or (n, 1), is used as it is (``column`` may then be 0 or -1). An
    attribute of several columns, (n, c) or (n, a, b...) flattened row-major like its PLY
    properties ``name_0 .. name_{c-1}``, needs ``column`` (0-based, negative counts from the end):
    without it, it is refused with a MeshError that lists the columns and says how to pick one.
    There is no silent default column.

    Parameters
    ----------
    values : array_like, (n,) or (n, ...)
        The attribute, one row per vertex (or point).
    name : str
        The attribute's name (for messages).
    column : int or None
        The column, 0-based, negative from the end (-1 the last); None: the attribute must have one
        column.
    option : str
        How the user picks a column, for the message: ``"column="`` (a filter parameter) or
        ``"--column "`` (a command option).

    Returns
    -------
    numpy.ndarray, (n,)

    Raises
    ------
    MeshError
        Several columns and no ``column``, or a column that does not exist.

    Examples
    --------
    >>> import numpy as np
    >>> from o3dheat.pipelines.filters import one_column
    >>> one_column(np.arange(6.0).reshape(3, 2), "f", column=-1).tolist()
    [1.0, 3.0, 5.0]
    >>> one_column(np.arange(6.0).reshape(3, 2), "f")
    Traceback (most recent call last):
    ...
    o3dheat.errors.MeshError: attribute 'f' has 2 columns (0..1): pick one with column=N (0 is the first, -1 the last)
    """
    a = np.asarray(values)
    a = a.reshape(len(a), -1) if a.ndim > 1 else a.reshape(len(a), 1)
    return a[:, check_column(a.shape[1], name, column, option)]


def check_column(count: int, name: str, column: int | None = None, option: str = "column=") -> int:
    """The column :func:`one_column` takes from an attribute of ``count`` columns, without its
    values (for checking a chain before running it, :meth:`~o3dheat.pipelines.filters.Chain.check`).

    Parameters
    ----------
    count : int
        The attribute's columns (1 for an (n,) attribute).
    name, column, option
        As for :func:`one_column`.

    Returns
    -------
    int
        The column's index (``column`` as given, or 0 for a one-column attribute).

    Raises
    ------
    MeshError
        As :func:`one_column`.

    Examples
    --------
    >>> from o3dheat.pipelines.filters import check_column
    >>> check_column(1, "height"), check_column(10, "hks", -1)
    (0, -1)
    >>> check_column(10, "hks")
    Traceback (most recent call last):
    ...
    o3dheat.errors.MeshError: attribute 'hks' has 10 columns (0..9): pick one with column=N (0 is the first, -1 the last)
    """
    c = int(count)
    if column is None:
        if c == 1:
            return 0
        raise MeshError(f"attribute {name!r} has {c} columns (0..{c - 1}): pick one with {option}N "
                        "(0 is the first, -1 the last)")
    if isinstance(column, bool) or not isinstance(column, (int, np.integer)):
        raise MeshError(f"the column of attribute {name!r} must be an integer, got {column!r}")
    if not -c <= column < c:
        cols = "1 column (0)" if c == 1 else f"{c} columns (0..{c - 1})"
        raise MeshError(f"attribute {name!r} has {cols}: column {column} does not exist")
    return column


def attribute_columns(geometry: typing.Any) -> dict[str, int]:
    """The per-vertex (or per-point) attributes of a geometry and their column counts: what a
    filter's ``plan`` reads (see :meth:`~o3dheat.pipelines.filters.Chain.check`).

    Parameters
    ----------
    geometry : Open3D TriangleMesh or PointCloud (tensor or legacy)
        The geometry whose vertex (mesh) or point (cloud) attributes are listed; positions included.

    Returns
    -------
    dict
        Name -> columns (1 for an (n,) attribute; trailing axes multiplied, as the filters flatten
        them).

    Examples
    --------
    >>> import open3d as o3d
    >>> from o3dheat.pipelines.filters import attribute_columns
    >>> attribute_columns(o3d.t.geometry.TriangleMesh.create_sphere(1.0, 4))
    {'positions': 3}
    """
    import open3d as o3d

    if isinstance(geometry, o3d.geometry.TriangleMesh):
        return {"positions": 3, **({"normals": 3} if geometry.has_vertex_normals() else {}),
                **({"colors": 3} if geometry.has_vertex_colors() else {})}
    if isinstance(geometry, o3d.geometry.PointCloud):
        return {"positions": 3, **({"normals": 3} if geometry.has_normals() else {}),
                **({"colors": 3} if geometry.has_colors() else {})}
    attrs = getattr(geometry, "vertex", None) if isinstance(geometry, o3d.t.geometry.TriangleMesh) else \
        getattr(geometry, "point", None) if isinstance(geometry, o3d.t.geometry.PointCloud) else None
    if attrs is None:
        return {}
    return {k: int(np.prod(attrs[k].shape[1:], dtype=np.int64)) for k in attrs}


#: vertex attributes no filter writes (the geometry itself)
PROTECTED = ("positions",)
#: vertex attributes Open3D gives a fixed shape: name -> trailing shape
SHAPED = {"normals": (3,), "colors": (3,)}
#: names no output may take: the PLY properties of positions, normals and colours (what every viewer
#: reads; ``alpha`` only for one column), and the exact colours o3dheat's PLY writer adds
PLY_RESERVED = ("x", "y", "z", "nx", "ny", "nz", "red", "green", "blue")
_OUTPUT_NAME = re.compile(r"[!-~]+\Z")  # printable ASCII, no whitespace: one PLY header token (o3dheat.io)


def _ply_properties(name, count):
    """The PLY properties o3dheat's writer stores an attribute of ``count`` columns under."""
    return [name] if count == 1 else [f"{name}_{j}" for j in range(count)]


def check_writable(name: str, columns: int | tuple[int, ...] | None = None,
                   attributes: dict[str, int] | None = None) -> None:
    """Refuse an output that cannot be written, with a MeshError naming it and why: the one check
    of every filter's outputs, run by :meth:`~o3dheat.pipelines.filters.Chain.check` on what each ``plan`` says it writes,
    by the built-in filters before their work (their plan) and when they write.

    Refused, as :func:`o3dheat.io.write_mesh <o3dheat.io.meshes.write_mesh>` would refuse them after the work: :data:`PROTECTED`
    (the geometry itself); a name that is not printable ASCII without spaces (a PLY property is
    one header token; empty text neither); :data:`PLY_RESERVED` names, ``alpha`` of several
    columns and ``o3dheat_colors*`` (PLY properties of their own); and :data:`SHAPED` names
    (``normals``, ``colors``) of another shape than Open3D's (n, 3).

    Parameters
    ----------
    name : str
        The output attribute's name.
    columns : int, tuple of int or None
        The output's columns (a ``plan``'s count) or its trailing shape (``values.shape[1:]``);
        None: the name only.
    attributes : dict or None
        The geometry's other attributes and their column counts (:func:`attribute_columns`): the
        output's PLY properties (``name``, or ``name_0 ..`` for several columns) may not be one of
        theirs (``a_0`` beside a 3-column ``a``).

    Examples
    --------
    >>> from o3dheat.pipelines.filters import check_writable
    >>> check_writable("height", 1); check_writable("colors", 3)
    >>> check_writable("positions")
    Traceback (most recent call last):
    ...
    o3dheat.errors.MeshError: refusing to overwrite 'positions'
    >>> check_writable("colors", 1)
    Traceback (most recent call last):
    ...
    o3dheat.errors.MeshError: output 'colors' must have shape (n, 3) (Open3D's colors), got 1 column: rename it
    """
    if name in PROTECTED:
        raise MeshError(f"refusing to overwrite {name!r}")
    if not isinstance(name, str) or not _OUTPUT_NAME.match(name):
        raise MeshError(f"output {name!r} is not a name a PLY property can hold (one header token: printable "
                        "ASCII without spaces): rename it")
    if name in PLY_RESERVED or name.startswith("o3dheat_colors"):
        raise MeshError(f"output {name!r} is a reserved PLY property ({' '.join(PLY_RESERVED)}: positions, "
                        "normals and colours; o3dheat_colors*): rename it")
    if columns is None:
        return
    trailing = (int(columns),) if isinstance(columns, (int, np.integer)) else tuple(int(c) for c in columns)
    count = int(np.prod(trailing, dtype=np.int64))
    if name == "alpha" and count != 1:
        raise MeshError(f"output 'alpha' has {count} columns: a PLY's alpha is one column: rename it")
    if name in SHAPED and trailing != SHAPED[name]:
        want = ", ".join(["n", *map(str, SHAPED[name])])
        got = f"shape (n, {', '.join(map(str, trailing))})" if len(trailing) > 1 else \
            f"{count} column" + ("" if count == 1 else "s")
        raise MeshError(f"output {name!r} must have shape ({want}) (Open3D's {name}), got {got}: rename it")
    if attributes:
        mine = set(_ply_properties(name, count))
        for other, c in attributes.items():
            if other == name or other in PROTECTED or other in SHAPED:  # overwritten / stored as x y z ...
                continue
            clash = sorted(mine.intersection(_ply_properties(other, int(c))))
            if clash:
                raise MeshError(f"output {name!r} ({count} column{'s' if count != 1 else ''}) would be stored "
                                f"as PLY property {clash[0]!r}, which attribute {other!r} has: rename it")



def check_step(step: typing.Any, columns: dict[str, int]) -> dict[str, int] | None:
    """What a filter writes on a geometry of attributes ``columns`` (:func:`attribute_columns`),
    checked before its work: its ``plan`` (which raises what its run would), then each output
    (:func:`check_writable`). Run by :meth:`~o3dheat.pipelines.filters.Chain.check` for each step and by the built-in
    filters when they start.

    Returns
    -------
    dict or None
        The attributes and column counts after the step; None for a filter without a plan
        (nothing can be said before it runs).

    Examples
    --------
    >>> import o3dheat.pipelines.filters as flt
    >>> flt.check_step(flt.get("hks", scales=4), {"positions": 3})
    {'positions': 3, 'hks': 4}
    >>> flt.check_step(flt.get("hks", output="colors"), {"positions": 3})
    Traceback (most recent call last):
    ...
    o3dheat.errors.MeshError: output 'colors' must have shape (n, 3) (Open3D's colors), got 10 columns: rename it
    """
    plan = _plan_of(step)
    if plan is None:
        return None
    written = plan(dict(columns))
    after = dict(columns)
    for name, count in written.items():
        check_writable(name, count, after)
        after[name] = count
    return after


def _plan_of(step):
    """A filter's ``plan``, bound, if the class that defines its ``__call__`` defines one (a
    subclass that runs differently does not inherit its parent's plan), else None."""
    owner = next((c for c in type(step).__mro__ if "__call__" in c.__dict__), None)
    plan = owner.__dict__.get("plan") if owner is not None else None
    return (lambda columns: plan(step, columns)) if callable(plan) else None


def need_attribute(columns: dict, name: str) -> int:
    """The column count of attribute ``name`` in ``columns`` (from :func:`attribute_columns`), or
    the MeshError a filter raises when the attribute is missing.

    Examples
    --------
    >>> from o3dheat.pipelines.filters import need_attribute
    >>> need_attribute({"positions": 3, "height": 1}, "height")
    1
    >>> need_attribute({"positions": 3}, "height")
    Traceback (most recent call last):
    ...
    o3dheat.errors.MeshError: no vertex attribute 'height'; this geometry has: positions
    """
    if name not in columns:
        raise MeshError(f"no vertex attribute {name!r}; this geometry has: {', '.join(sorted(columns))}")
    return columns[name]
