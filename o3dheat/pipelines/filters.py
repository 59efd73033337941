"""Filters: the protocol, the registry and chains.

A filter is a small frozen dataclass whose typed fields are its parameters. Calling it on a mesh
returns a **new** ``o3d.t.geometry.TriangleMesh`` with every attribute of the input kept and its
own outputs added (the input is never changed); point clouds give point clouds (see
:mod:`o3dheat.geometry`). Filters are found through the entry-point group ``o3dheat.filters``,
lazily: o3dheat's own (the ``o3dheat_filters`` package) are registered there exactly like a
third-party plugin would be::

    # pyproject.toml of a plugin
    [project.entry-points."o3dheat.filters"]
    my_filter = "my_package.my_module:MyFilter"

A chain is a list of configured filters; it can be saved to and loaded from a TOML file::

    [[filter]]
    name = "scalar"
    kind = "height"

    [[filter]]
    name = "heat_smooth"
    attribute = "height"

All filters of a chain, and of a Python session, share one spectrum per mesh and solver
settings (:func:`shared_spectrum`).
"""

from __future__ import annotations

import dataclasses
import difflib
import re
import sys
import typing
from importlib import metadata
from pathlib import Path

import numpy as np

from o3dheat.errors import MeshError

__all__ = ["GROUP", "names", "describe", "get", "apply", "Chain", "Parameter", "OneOf", "Limits", "param",
           "check_parameters", "shared_spectrum", "set_disk_cache", "parse_value", "refresh", "one_column",
           "check_column", "attribute_columns", "need_attribute", "check_writable", "check_step", "PROTECTED",
           "SHAPED", "PLY_RESERVED", "plain_text"]

GROUP = "o3dheat.filters"

_EPS: dict | None = None
_CLASSES: dict = {}


def _entry_points():
    global _EPS
    if _EPS is None:
        eps = metadata.entry_points(group=GROUP)
        _EPS = {ep.name: ep for ep in sorted(eps, key=lambda e: e.name)}
    return _EPS


def refresh():
    """Forget the discovered filters (after installing a plugin in a running session).

    Examples
    --------
    >>> import o3dheat.pipelines.filters as flt
    >>> flt.refresh()
    >>> "hks" in flt.names()          # found again, lazily
    True
    """
    global _EPS
    import importlib

    _EPS = None
    _CLASSES.clear()
    importlib.invalidate_caches()


def names():
    """Names of every installed filter, sorted.

    Examples
    --------
    >>> import o3dheat.pipelines.filters as flt
    >>> {"heat_smooth", "hks", "colorize"} <= set(flt.names())
    True
    """
    return list(_entry_points())


def _class(name):
    if name in _CLASSES:
        return _CLASSES[name]
    eps = _entry_points()
    if name not in eps:
        close = difflib.get_close_matches(name, list(eps), n=3, cutoff=0.6)
        hint = f" (did you mean {', '.join(close)}?)" if close else ""
        raise MeshError(f"unknown filter {name!r}{hint}; installed: {', '.join(eps) or 'none'}")
    try:
        cls = eps[name].load()
    except Exception as e:
        raise MeshError(f"filter {name!r} could not be loaded from {eps[name].value}: {e}") from e
    if not (dataclasses.is_dataclass(cls) and callable(cls)):
        raise MeshError(f"filter {name!r} ({eps[name].value}) is not a dataclass filter")
    _CLASSES[name] = cls
    return cls


@dataclasses.dataclass(frozen=True)
class Parameter:
    """One parameter of a filter: name, type (as text), default and help (from the docstring).

    Examples
    --------
    >>> import o3dheat.pipelines.filters as flt
    >>> p = flt.describe("hks")["parameters"][0]
    >>> p.name, p.type, p.default, p.limits
    ('scales', 'int', 10, 'in [1, 100000]')
    """

    name: str
    type: str
    default: typing.Any
    help: str
    limits: str = ""

    def __str__(self):
        limits = f", {self.limits}" if self.limits else ""
        return f"{self.name} ({self.type}{limits}, default {self.default!r}): {self.help}"


def _doc_params(doc):
    """Parameter help from a numpydoc "Parameters" section: {name: text}."""
    lines = (doc or "").splitlines()
    try:
        start = next(i for i, ln in enumerate(lines) if ln.strip() == "Parameters")
    except StopIteration:
        return {}
    out, name = {}, None
    for ln in lines[start + 2:]:
        if ln.strip() and set(ln.strip()) == {"-"}:  # the next section's underline
            if name:
                out[name].pop()  # that section's title
            break
        m = re.match(r"^\s{4}(\w+)\s*:", ln)
        if m:
            name = m.group(1)
            out[name] = []
        elif name and ln.strip():
            out[name].append(ln.strip())
    return {k: " ".join(v) for k, v in out.items()}


class OneOf:
    """A filter parameter's choices that are defined elsewhere and read when a value is checked,
    never copied: annotate the field ``typing.Annotated[str, OneOf(lambda: CHOICES)]``.

    The built-in filters' ``variant`` is ``Annotated[str, OneOf(lambda: o3dheat.spectral.kernel.VARIANTS)]``:
    a variant added to :data:`o3dheat.spectral.kernel.VARIANTS` is accepted at once, and :func:`describe`
    lists the choices of the moment (as ``Literal[...]``, like a fixed ``typing.Literal``).

    Parameters
    ----------
    choices : callable
        Returns the allowed values (any iterable: a tuple, the keys of a dict...).

    Examples
    --------
    >>> import typing
    >>> from o3dheat.pipelines.filters import OneOf
    >>> colours = {"red": 1, "blue": 2}
    >>> Colour = typing.Annotated[str, OneOf(lambda: colours)]
    >>> colours["green"] = 3                 # defined later: still accepted
    >>> OneOf.of(Colour).choices()
    ('red', 'blue', 'green')
    """

    def __init__(self, choices):
        if not callable(choices):
            raise TypeError("OneOf takes a callable returning the choices (read when a value is checked)")
        self._choices = choices

    def choices(self):
        """The allowed values now, as a tuple.

        Examples
        --------
        >>> from o3dheat.pipelines.filters import OneOf
        >>> OneOf(lambda: ("a", "b")).choices()
        ('a', 'b')
        """
        return tuple(self._choices())

    @staticmethod
    def of(tp):
        """The :class:`OneOf` of an annotation ``Annotated[..., OneOf(...)]``, else None.

        Examples
        --------
        >>> import typing
        >>> from o3dheat.pipelines.filters import OneOf
        >>> OneOf.of(typing.Annotated[str, OneOf(lambda: "ab")]).choices(), OneOf.of(str)
        (('a', 'b'), None)
        """
        if typing.get_origin(tp) is typing.Annotated:
            return next((m for m in tp.__metadata__ if isinstance(m, OneOf)), None)
        return None

    def __repr__(self):
        return "OneOf(" + ", ".join(map(repr, self.choices())) + ")"


_LIMITS = "o3dheat.limits"  # the key of a dataclass field's metadata that holds its Limits


@dataclasses.dataclass(frozen=True)
class Limits:
    """The bounds of a filter parameter, declared with it (:func:`param`) and checked with its type
    wherever a value comes in: :func:`get` (so :meth:`Chain.load`, the command's ``-f``),
    :meth:`Chain.append` and :meth:`Chain.check` (instances made directly), and the built-in
    filters' construction: always before any work.

    Numbers (a number, or each item of a list) must satisfy ``ge <= x``, ``gt < x``, ``x <= le``,
    ``x < lt`` (those given); lists must hold ``min_len`` to ``max_len`` items. None (a parameter's
    "not given") is not checked.

    Examples
    --------
    >>> from o3dheat.pipelines.filters import Limits
    >>> str(Limits(gt=0, le=1)), str(Limits(ge=0, min_len=1))
    ('in (0, 1]', '>= 0, at least 1 value')
    >>> Limits(gt=0, le=1).check(0.0, "f.keep_fraction")
    Traceback (most recent call last):
    ...
    o3dheat.errors.MeshError: f.keep_fraction must be in (0, 1], got 0.0
    """

    ge: float | None = None
    gt: float | None = None
    le: float | None = None
    lt: float | None = None
    min_len: int | None = None
    max_len: int | None = None

    def _numbers(self):
        lo = f"[{self.ge:g}" if self.ge is not None else f"({self.gt:g}" if self.gt is not None else None
        hi = f"{self.le:g}]" if self.le is not None else f"{self.lt:g})" if self.lt is not None else None
        if lo and hi:
            return f"in {lo}, {hi}"
        if lo:
            return (">= " if lo[0] == "[" else "> ") + lo[1:]
        if hi:
            return ("<= " if hi[-1] == "]" else "< ") + hi[:-1]
        return ""

    def _length(self):
        lo, hi = self.min_len, self.max_len
        if lo is None and hi is None:
            return ""
        plural = (lambda c: f"{c} value" + ("" if c == 1 else "s"))
        if lo == hi:
            return f"exactly {plural(lo)}"
        if hi is None:
            return f"at least {plural(lo)}"
        if lo is None:
            return f"at most {plural(hi)}"
        return f"{lo} to {plural(hi)}"

    def __str__(self):
        return ", ".join(t for t in (self._numbers(), self._length()) if t)

    def _number_ok(self, x):
        return ((self.ge is None or x >= self.ge) and (self.gt is None or x > self.gt)
                and (self.le is None or x <= self.le) and (self.lt is None or x < self.lt))

    def check(self, value, where):
        """``value`` (already of the parameter's type) within the bounds, else a MeshError naming
        ``where`` and the bounds.

        Examples
        --------
        >>> from o3dheat.pipelines.filters import Limits
        >>> Limits(ge=0, min_len=1).check((0.1, 2.0), "hks.times")
        >>> Limits(ge=0, min_len=1).check((), "hks.times")
        Traceback (most recent call last):
        ...
        o3dheat.errors.MeshError: hks.times must have at least 1 value (None for the default), got ()
        """
        if value is None:
            return
        if isinstance(value, (tuple, list)):
            n = len(value)
            if (self.min_len is not None and n < self.min_len) or (self.max_len is not None and n > self.max_len):
                default = " (None for the default)" if self.min_len and not n else ""
                raise MeshError(f"{where} must have {self._length()}{default}, got {value!r}")
            items = value
        else:
            items = (value,)
        for x in items:
            if isinstance(x, (int, float, np.integer, np.floating)) and not isinstance(x, bool) \
                    and not self._number_ok(x):
                which = "" if items is not value else " (every value)"
                raise MeshError(f"{where} must be {self._numbers()}{which}, got {value!r}")

    @staticmethod
    def of(field):
        """The :class:`Limits` a dataclass field was declared with (:func:`param`), else None.

        Examples
        --------
        >>> import dataclasses, o3dheat.pipelines.filters as flt
        >>> [str(flt.Limits.of(f)) for f in dataclasses.fields(flt.get("hks")) if f.name == "k"]
        ['>= 1']
        """
        return field.metadata.get(_LIMITS) if field.metadata else None


def param(default=None, **limits):
    """A filter parameter with bounds: ``delta: float | None = param(None, ge=0)``, a dataclass field
    whose metadata holds its :class:`Limits` (``ge``, ``gt``, ``le``, ``lt``, ``min_len``,
    ``max_len``), listed by :func:`describe` and checked before any work (see :class:`Limits`).

    Examples
    --------
    >>> import dataclasses
    >>> from o3dheat.pipelines.filters import param
    >>> @dataclasses.dataclass(frozen=True)
    ... class Blur:
    ...     sigma: float = param(1.0, gt=0)
    ...     def __call__(self, mesh):
    ...         return mesh
    >>> import o3dheat.pipelines.filters as flt
    >>> flt.check_parameters(Blur(sigma=-1.0))
    Traceback (most recent call last):
    ...
    o3dheat.errors.MeshError: Blur.sigma must be > 0, got -1.0
    """
    return dataclasses.field(default=default, metadata={_LIMITS: Limits(**limits)})


def _type_text(tp):
    if tp in (int, float, str, bool):
        return tp.__name__
    one_of = OneOf.of(tp)
    if one_of is not None:
        return "Literal[" + ", ".join(map(repr, one_of.choices())) + "]"
    return str(tp).replace("typing.", "")


def _hints(cls):
    """The parameters' annotations, each resolved in the module of the class that declares it (a
    plugin's subclass of a built-in filter keeps the built-in's types); {} when they cannot be
    resolved (names local to a function): the values are then taken as they are."""
    try:
        return typing.get_type_hints(cls, include_extras=True)
    except Exception:
        return {}


def describe(name):
    """What a filter does and its parameters.

    Returns
    -------
    dict
        ``name``, ``summary`` (the docstring's first paragraph on one line, as plain text:
        :func:`plain_text`), ``doc`` (whole docstring, as written), ``outputs`` (attribute names
        it writes, when declared) and ``parameters`` (list of :class:`Parameter`, their help as
        plain text, their bounds as declared with :func:`param`).

    Examples
    --------
    >>> import o3dheat.pipelines.filters as flt
    >>> [p.name for p in flt.describe("hks")["parameters"]][:2]
    ['scales', 'times']
    >>> flt.describe("hks")["summary"]
    'Heat kernel signatures at several scales (paper §2.2) -> hks (n, T).'
    """
    cls = _class(name)
    doc = cls.__doc__ or ""
    helps = _doc_params(doc)
    hints = _hints(cls)
    params = []
    for f in dataclasses.fields(cls):
        default = f.default if f.default is not dataclasses.MISSING else (
            f.default_factory() if f.default_factory is not dataclasses.MISSING else None)
        limits = Limits.of(f)
        params.append(Parameter(f.name, _type_text(hints.get(f.name, typing.Any)), default,
                                plain_text(helps.get(f.name, "")), str(limits) if limits else ""))
    summary = plain_text(re.split(r"\n\s*\n", doc.strip(), maxsplit=1)[0]) if doc.strip() else ""
    return {"name": name, "summary": summary, "doc": doc, "parameters": params,
            "outputs": getattr(cls, "outputs", None)}


def plain_text(text):
    r"""The reStructuredText of a docstring as plain one-line text: ````literal```` and ```x``` lose their
    backticks, roles keep their text (``:func:`~a.b` `` -> ``b``, ``:class:`T <a.T>` `` -> ``T``),
    a trailing ``::`` becomes ``:``, and lines are joined.

    Examples
    --------
    >>> from o3dheat.pipelines.filters import plain_text
    >>> plain_text("Smooth ``f`` with\n    :func:`~o3dheat.spectral.kernel.smooth` (see :class:`HeatKernel <o3dheat.HeatKernel>`)::")
    'Smooth f with smooth (see HeatKernel):'
    """
    def role(m):
        body = m.group(1)
        label = re.match(r"(.*?)\s*<[^<>]*>$", body, re.S)
        if label and label.group(1):
            return label.group(1)
        body = body.lstrip("!")
        return body.rsplit(".", 1)[-1] if body.startswith("~") else body

    text = re.sub(r"(?::[\w.+-]+)+:`([^`]*)`", role, text)
    text = re.sub(r"``(.+?)``", r"\1", text, flags=re.S)
    text = re.sub(r"`([^`]+)`_{0,2}", r"\1", text)
    text = " ".join(text.split())
    return text[:-1] if text.endswith("::") else text


def one_column(values, name, column=None, option="column="):
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


def check_column(count, name, column=None, option="column="):
    """The column :func:`one_column` takes from an attribute of ``count`` columns, without its
    values (for checking a chain before running it, :meth:`Chain.check`).

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


def attribute_columns(geometry):
    """The per-vertex (or per-point) attributes of a geometry and their column counts: what a
    filter's ``plan`` reads (see :meth:`Chain.check`).

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


def check_writable(name, columns=None, attributes=None):
    """Refuse an output that cannot be written, with a MeshError naming it and why: the one check
    of every filter's outputs, run by :meth:`Chain.check` on what each ``plan`` says it writes,
    by the built-in filters before their work (their plan) and when they write.

    Refused, as :func:`o3dheat.io.write_mesh` would refuse them after the work: :data:`PROTECTED`
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


def check_step(step, columns):
    """What a filter writes on a geometry of attributes ``columns`` (:func:`attribute_columns`),
    checked before its work: its ``plan`` (which raises what its run would), then each output
    (:func:`check_writable`). Run by :meth:`Chain.check` for each step and by the built-in
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


def need_attribute(columns, name):
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


# ------------------------------------------------------------------------------- parameters
def _check(tp, value, where):
    """``value`` checked (and converted where lossless) against the annotation ``tp``."""
    origin = typing.get_origin(tp)
    args = typing.get_args(tp)
    if tp is typing.Any:
        return value
    if origin is typing.Annotated:
        value = _check(args[0], value, where)
        one_of = OneOf.of(tp)
        if one_of is not None and value not in one_of.choices():
            raise MeshError(f"{where} must be one of {', '.join(map(repr, one_of.choices()))}, got {value!r}")
        return value
    if origin is typing.Union or (sys.version_info >= (3, 10) and origin is __import__("types").UnionType):
        if value is None and type(None) in args:
            return None
        errors = []
        for a in args:
            if a is type(None):
                continue
            try:
                return _check(a, value, where)
            except MeshError as e:
                errors.append(str(e))
        raise MeshError(errors[0] if errors else f"{where}: bad value {value!r}")
    if origin is typing.Literal:
        if value not in args:
            raise MeshError(f"{where} must be one of {', '.join(map(repr, args))}, got {value!r}")
        return value
    if origin in (tuple, list):
        if isinstance(value, (str, bytes)) or not isinstance(value, (tuple, list, np.ndarray)):
            raise MeshError(f"{where} must be a list, got {value!r}")
        item = args[0] if args else typing.Any
        return tuple(_check(item, v, where) for v in value)
    if tp is bool:
        if isinstance(value, (bool, np.bool_)):
            return bool(value)
        raise MeshError(f"{where} must be true or false, got {value!r}")
    if tp is int:
        if isinstance(value, (int, np.integer)) and not isinstance(value, bool):
            return int(value)
        raise MeshError(f"{where} must be an integer, got {value!r}")
    if tp is float:
        if isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(value, bool):
            v = float(value)
            if not np.isfinite(v):
                raise MeshError(f"{where} must be a finite number, got {value!r}")
            return v
        raise MeshError(f"{where} must be a number, got {value!r}")
    if tp is str:
        if isinstance(value, str):
            return value
        raise MeshError(f"{where} must be text, got {value!r}")
    return value


def parse_value(text, tp):
    """A parameter value from command-line text, for the annotation ``tp``.

    List items are separated by ``+`` (or ``;``): ``times=0.1+0.2``; a comma cannot be used, it
    separates the parameters of ``-f NAME:key=value,key=value``. An exponent's sign stays with
    its number (``1e+3+2`` is 1000 and 2). ``none`` is None; ``true``/``false`` are booleans.

    Examples
    --------
    >>> from o3dheat.pipelines.filters import parse_value
    >>> parse_value("0.5+1", tuple[float, ...]), parse_value("3", int), parse_value("none", int | None)
    ((0.5, 1.0), 3, None)
    >>> parse_value("1e-2+1e+2", tuple[float, ...])
    (0.01, 100.0)
    """
    origin, args = typing.get_origin(tp), typing.get_args(tp)
    if origin is typing.Annotated:  # its metadata is checked with the value (get)
        return parse_value(text, args[0])
    low = text.strip().lower()
    if origin is typing.Union or (sys.version_info >= (3, 10) and origin is __import__("types").UnionType):
        if low in ("none", "null", "") and type(None) in args:
            return None
        for a in args:
            if a is type(None):
                continue
            try:
                return parse_value(text, a)
            except (ValueError, MeshError):
                continue
        raise MeshError(f"cannot read {text!r} as {_type_text(tp)}")
    if origin in (tuple, list):
        item = args[0] if args else str
        return tuple(parse_value(t, item) for t in re.split(r";|(?<![0-9.][eE])\+", text) if t.strip())
    if origin is typing.Literal:  # a choice written as text: "none" is None when None is a choice
        if low in ("none", "null") and None in args:
            return None
        return next((a for a in args if not isinstance(a, str) and str(a).lower() == low), text)
    if tp is bool:
        if low in ("true", "yes", "1", "on"):
            return True
        if low in ("false", "no", "0", "off"):
            return False
        raise MeshError(f"cannot read {text!r} as true/false")
    if tp is int:
        try:
            return int(text)
        except ValueError:
            raise MeshError(f"cannot read {text!r} as an integer") from None
    if tp is float:
        try:
            return float(text)
        except ValueError:
            raise MeshError(f"cannot read {text!r} as a number") from None
    return text


def get(name, **params):
    """A configured filter.

    Parameters
    ----------
    name : str
        A name from :func:`names`.
    **params
        Parameters (see :func:`describe`); unknown names and wrong types raise MeshError.

    Returns
    -------
    The filter instance: ``filter(mesh) -> new mesh``.

    Examples
    --------
    >>> import o3dheat.pipelines.filters as flt
    >>> flt.get("colorize", attribute="hks", column=3)
    Colorize(attribute='hks', column=3, colormap='coolwarm', range=None, output='colors')
    """
    cls = _class(name)
    hints = _hints(cls)
    fields = {f.name: f for f in dataclasses.fields(cls)}
    unknown = sorted(set(params) - set(fields))
    if unknown:
        raise MeshError(f"filter {name!r} has no parameter {', '.join(map(repr, unknown))}; "
                        f"its parameters: {', '.join(fields)}")
    checked = {k: _check_field(fields[k], hints, v, f"{name}.{k}") for k, v in params.items()}
    try:
        return cls(**checked)
    except TypeError as e:
        raise MeshError(f"filter {name!r}: {e}") from e


def _check_field(field, hints, value, where):
    """A parameter's value checked against its annotation (:func:`_check`), then its bounds."""
    value = _check(hints.get(field.name, typing.Any), value, where)
    limits = Limits.of(field)
    if limits is not None:
        limits.check(value, where)
    return value


def check_parameters(step):
    """Every parameter of a filter instance checked against its type and bounds (:func:`param`),
    as :func:`get` checks the ones it is given: the values, converted where lossless (an int for
    a float, a list for a tuple), by name. :meth:`Chain.append` and :meth:`Chain.check` run it on
    every step (a filter made directly, not by name, is checked too), and the built-in filters at
    construction.

    Returns
    -------
    dict
        Parameter name -> value.

    Raises
    ------
    MeshError
        ``<filter>.<parameter> must be ..., got ...``.

    Examples
    --------
    >>> import o3dheat.pipelines.filters as flt
    >>> flt.check_parameters(flt.get("colorize", attribute="hks", column=3))["column"]
    3
    """
    cls = type(step)
    hints, name = _hints(cls), _name_of(step)
    return {f.name: _check_field(f, hints, getattr(step, f.name), f"{name}.{f.name}")
            for f in dataclasses.fields(cls) if f.init}


def apply(mesh, name, **params):
    """Run one filter: ``get(name, **params)(mesh)``.

    Examples
    --------
    >>> import open3d as o3d, o3dheat.pipelines.filters as flt
    >>> out = flt.apply(o3d.t.geometry.TriangleMesh.create_sphere(1.0, 10), "hks", k=20)
    >>> out.vertex["hks"].shape
    SizeVector[182, 10]
    """
    return get(name, **params)(mesh)


def _name_of(flt):
    cls = type(flt)
    for n, ep in _entry_points().items():
        if _CLASSES.get(n) is cls or ep.value == f"{cls.__module__}:{cls.__qualname__}":
            return n
    return getattr(cls, "name", cls.__name__)


class Chain:
    """A list of configured filters run one after the other.

    Parameters
    ----------
    steps : iterable of filters or of ``(name, params)`` pairs

    Examples
    --------
    >>> import open3d as o3d, o3dheat.pipelines.filters as flt
    >>> chain = flt.Chain([("scalar", {"kind": "height"}), ("heat_smooth", {"attribute": "height", "k": 20}),
    ...                    ("colorize", {"attribute": "height_smooth", "column": 4})])
    >>> out = chain(o3d.t.geometry.TriangleMesh.create_sphere(1.0, 10))
    >>> sorted(k for k in out.vertex)
    ['colors', 'height', 'height_smooth', 'positions']
    """

    def __init__(self, steps=()):
        self.steps = []
        for s in steps:
            self.append(s)

    def append(self, step, **params):
        """Add a filter (an instance, a name with params, or a (name, params) pair).

        Returns
        -------
        Chain
            This chain (calls can be chained).

        Examples
        --------
        >>> import o3dheat.pipelines.filters as flt
        >>> chain = flt.Chain().append("scalar", kind="height").append(("hks", {"k": 20}))
        >>> len(chain)
        2
        """
        if isinstance(step, str):
            step = get(step, **params)
        elif isinstance(step, (tuple, list)) and len(step) == 2 and isinstance(step[0], str):
            step = get(step[0], **dict(step[1]))
        elif not (dataclasses.is_dataclass(step) and callable(step)):
            raise MeshError(f"a chain step must be a filter or (name, params), got {step!r}")
        else:
            check_parameters(step)  # made directly: its parameters were not checked by get
        self.steps.append(step)
        return self

    def __len__(self):
        return len(self.steps)

    def __iter__(self):
        return iter(self.steps)

    def __repr__(self):
        return "Chain([" + ", ".join(map(repr, self.steps)) + "])"

    def __call__(self, mesh, progress=None):
        """Run every step on the result of the previous one; ``progress(i, step)`` is called first.

        Examples
        --------
        >>> import open3d as o3d, o3dheat.pipelines.filters as flt
        >>> chain = flt.Chain([("scalar", {"kind": "height"})])
        >>> out = chain(o3d.t.geometry.TriangleMesh.create_sphere(1.0, 8), progress=lambda i, step: print(i))
        0
        >>> "height" in out.vertex
        True
        """
        self.check(mesh)
        for i, step in enumerate(self.steps):
            if progress:
                progress(i, step)
            mesh = step(mesh)
        return mesh

    def check(self, geometry):
        """Check the chain against a geometry's attributes before any work: a parameter out of its
        type or bounds (:func:`check_parameters`, every step), a step that reads an attribute the
        steps before it do not make, or a column it does not have, is refused at once (not after
        an eigensolve of a million vertices, or of every file of a batch).

        Each filter with a ``plan(columns)`` method takes the attributes' column counts
        (:func:`attribute_columns`), raises the MeshError its run would raise, and returns the
        column counts of what it writes, each of which must be writable (:func:`check_writable`:
        not ``positions``, a PLY/Open3D name, ``colors``/``normals`` of 3 columns): :func:`check_step`.
        Checking stops at the first filter without one (a plugin may have none; a subclass that
        defines its own ``__call__`` but not its own ``plan`` has none either): what follows it is
        checked when it runs, as always.

        Parameters
        ----------
        geometry : Open3D TriangleMesh or PointCloud
            The chain's input: only its attributes and their column counts are read.

        Returns
        -------
        dict
            The attributes and column counts after the last planned step.

        Raises
        ------
        MeshError
            Naming the step (its position and filter) and the problem.

        Examples
        --------
        >>> import open3d as o3d, o3dheat.pipelines.filters as flt
        >>> chain = flt.Chain([("hks", {"k": 20}), ("colorize", {"attribute": "hks"})])
        >>> chain.check(o3d.t.geometry.TriangleMesh.create_sphere(1.0, 4))
        Traceback (most recent call last):
        ...
        o3dheat.errors.MeshError: step 2 (colorize): attribute 'hks' has 10 columns (0..9): pick one with column=N (0 is the first, -1 the last)
        """
        for i, step in enumerate(self.steps):  # every step's parameters, planned or not
            try:
                check_parameters(step)
            except MeshError as e:
                raise MeshError(f"step {i + 1} ({_name_of(step)}): {e}") from None
        columns = attribute_columns(geometry)
        for i, step in enumerate(self.steps):
            try:
                after = check_step(step, columns)
            except MeshError as e:
                raise MeshError(f"step {i + 1} ({_name_of(step)}): {e}") from None
            if after is None:
                break
            columns = after
        return columns

    def to_dict(self):
        """The chain as plain data: ``{"filter": [{"name": ..., parameter: value, ...}, ...]}`` (None
        values left out), as written by :meth:`save`.

        Examples
        --------
        >>> import o3dheat.pipelines.filters as flt
        >>> flt.Chain([("colorize", {"attribute": "hks", "column": 3})]).to_dict()
        {'filter': [{'name': 'colorize', 'attribute': 'hks', 'column': 3, 'colormap': 'coolwarm', 'output': 'colors'}]}
        """
        return {"filter": [{"name": _name_of(s), **_plain(dataclasses.asdict(s))} for s in self.steps]}

    def save(self, path):
        """Write the chain as TOML (atomically).

        Examples
        --------
        >>> import os, tempfile, o3dheat.pipelines.filters as flt
        >>> path = os.path.join(tempfile.mkdtemp(), "chain.toml")
        >>> flt.Chain([("scalar", {"kind": "height"})]).save(path)
        >>> print(open(path).read().splitlines()[2])
        [[filter]]
        """
        from o3dheat.io import atomic_write_text

        atomic_write_text(path, _to_toml(self.to_dict()))

    @classmethod
    def load(cls, path):
        """Read a chain from a TOML file (``[[filter]]`` tables with ``name`` and parameters).

        Examples
        --------
        >>> import os, tempfile, o3dheat.pipelines.filters as flt
        >>> path = os.path.join(tempfile.mkdtemp(), "chain.toml")
        >>> flt.Chain([("scalar", {"kind": "height"}), ("hks", {"k": 20})]).save(path)
        >>> [type(step).__name__ for step in flt.Chain.load(path)]
        ['Scalar', 'Hks']
        """
        from o3dheat.io import read_toml

        path = Path(path)
        if not path.is_file():
            raise MeshError(f"cannot read chain {path}: no such file")
        data = read_toml(path)
        steps = data.get("filter")
        if not isinstance(steps, list) or not all(isinstance(s, dict) and "name" in s for s in steps):
            raise MeshError(f"{path}: expected [[filter]] tables, each with a name")
        chain = cls()
        for s in steps:
            s = dict(s)
            chain.append(s.pop("name"), **s)
        return chain


def _plain(d):
    return {k: (list(v) if isinstance(v, tuple) else v) for k, v in d.items() if v is not None}


def _to_toml(data):
    def val(v):
        if isinstance(v, bool):
            return "true" if v else "false"
        if isinstance(v, (int, float)):
            return repr(v)
        if isinstance(v, str):
            return '"' + v.replace("\\", "\\\\").replace('"', '\\"') + '"'
        if isinstance(v, (list, tuple)):
            return "[" + ", ".join(val(x) for x in v) + "]"
        raise MeshError(f"cannot write {v!r} to TOML")

    out = ["# o3dheat filter chain: o3dheat apply IN OUT --chain this.toml"]
    for step in data["filter"]:
        out.append("\n[[filter]]")
        out += [f"{k} = {val(v)}" for k, v in step.items()]
    return "\n".join(out) + "\n"


# ------------------------------------------------------------------------ the shared spectrum
def set_disk_cache(folder):
    """Also keep the filters' spectra on disk: a folder, True (``o3dheat.spectral.spectrum.default_cache_dir()``)
    or None (memory only, the default): :func:`o3dheat.spectral.spectrum.set_cache`.

    Examples
    --------
    >>> import tempfile, o3dheat.pipelines.filters as flt
    >>> flt.set_disk_cache(tempfile.mkdtemp()); flt.set_disk_cache(None)
    """
    from o3dheat.spectral import set_cache

    set_cache(folder)


def shared_spectrum(V, F, k=100, mass="consistent", cache=None):
    """The spectrum the filters share: :func:`o3dheat.spectral.spectrum.shared_eigensolve` (one eigensolve
    per geometry and settings for a whole chain; the spectrum module holds the one cache).

    Returns
    -------
    Spectrum

    Examples
    --------
    >>> import open3d as o3d, o3dheat
    >>> V, F = o3dheat.as_arrays(o3d.t.geometry.TriangleMesh.create_sphere(1.0, 8))
    >>> s = o3dheat.pipelines.filters.shared_spectrum(V, F, k=5)
    >>> s is o3dheat.pipelines.filters.shared_spectrum(V, F, k=5)      # computed once
    True
    """
    from o3dheat.spectral import shared_eigensolve

    return shared_eigensolve(V, F, k=k, mass=mass, cache=cache)
