"""Filters: the protocol, the registry (:func:`names`, :func:`get`, :func:`describe`, :func:`apply`) and :class:`Chain`.

A filter is a frozen dataclass whose typed fields are its parameters (types and bounds:
``o3dheat.pipelines._params``; columns and outputs: :mod:`o3dheat.pipelines.columns`; every name
of both is reachable from here); called on a mesh it returns a **new** tensor geometry with the
input's attributes and its own outputs. Filters are found, lazily, in the entry-point group
:data:`GROUP`: o3dheat's own (``o3dheat_filters``, written with :mod:`o3dheat.pipelines.site`) as a
plugin's would be.

Notes
-----
A plugin registers ``my_filter = "my_package.my_module:MyFilter"`` under
``[project.entry-points."o3dheat.filters"]`` in its ``pyproject.toml``. A chain is saved to and
loaded from TOML as ``[[filter]]`` tables (``name = "scalar"``, then its parameters). All filters
of a chain, and of a session, share one spectrum per mesh and settings (:func:`shared_spectrum`).
The specification of filters, chains and plugins: ``docs/details/filters.md``.
"""

from __future__ import annotations

import dataclasses
import difflib
import importlib
import re
import typing
from importlib import metadata
from pathlib import Path

from o3dheat import spectral
from o3dheat.errors import MeshError, NoSuchFile
from o3dheat.io import atomic_write_text, read_toml
from o3dheat.typing import PathLike

from ._params import (
    Limits,
    OneOf,
    Parameter,
    check_field,
    doc_params,
    hints,
    param,
    parse_value,
    plain_text,
    type_text,
)
from .columns import (
    PLY_RESERVED,
    PROTECTED,
    SHAPED,
    attribute_columns,
    check_column,
    check_step,
    check_writable,
    need_attribute,
    one_column,
)

__all__ = ["GROUP", "names", "describe", "get", "apply", "parameter_types", "Chain", "Parameter", "OneOf", "Limits",
           "param", "check_parameters", "shared_spectrum", "set_disk_cache", "parse_value", "refresh", "one_column",
           "check_column", "attribute_columns", "need_attribute", "check_writable", "check_step", "PROTECTED",
           "SHAPED", "PLY_RESERVED", "plain_text"]

#: the entry-point group filters are registered in
GROUP = "o3dheat.filters"

_EPS: dict | None = None
_CLASSES: dict = {}


def _entry_points():
    global _EPS
    if _EPS is None:
        eps = metadata.entry_points(group=GROUP)
        _EPS = {ep.name: ep for ep in sorted(eps, key=lambda e: e.name)}
    return _EPS


def refresh() -> None:
    """Forget the discovered filters (after installing a plugin in a running session).

    Examples
    --------
    >>> import o3dheat.pipelines.filters as flt
    >>> flt.refresh()
    >>> "hks" in flt.names()          # found again, lazily
    True
    """
    global _EPS
    _EPS = None
    _CLASSES.clear()
    importlib.invalidate_caches()


def names() -> list[str]:
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



def describe(name: str) -> dict:
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
    helps = doc_params(doc)
    known = hints(cls)
    params = []
    for f in dataclasses.fields(cls):
        default = f.default if f.default is not dataclasses.MISSING else (
            f.default_factory() if f.default_factory is not dataclasses.MISSING else None)
        limits = Limits.of(f)
        params.append(Parameter(f.name, type_text(known.get(f.name, typing.Any)), default,
                                plain_text(helps.get(f.name, "")), str(limits) if limits else ""))
    summary = plain_text(re.split(r"\n\s*\n", doc.strip(), maxsplit=1)[0]) if doc.strip() else ""
    return {"name": name, "summary": summary, "doc": doc, "parameters": params,
            "outputs": getattr(cls, "outputs", None)}


def parameter_types(name: str) -> dict:
    """The types of a filter's parameters, resolved: ``{parameter: annotation}`` (what :func:`get`
    checks values against and the command line reads ``-f NAME:key=value`` text with,
    :func:`parse_value`).

    Parameters
    ----------
    name : str
        A name from :func:`names`.

    Raises
    ------
    MeshError
        An unknown filter, or annotations that cannot be resolved (:func:`o3dheat.pipelines._params.hints`).

    Examples
    --------
    >>> import o3dheat.pipelines.filters as flt
    >>> flt.parameter_types("hks")["scales"]
    <class 'int'>
    """
    return hints(_class(name))


# ------------------------------------------------------------------------------- parameters

def get(name: str, **params: typing.Any) -> typing.Any:
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
    known = hints(cls)
    fields = {f.name: f for f in dataclasses.fields(cls)}
    unknown = sorted(set(params) - set(fields))
    if unknown:
        raise MeshError(f"filter {name!r} has no parameter {', '.join(map(repr, unknown))}; "
                        f"its parameters: {', '.join(fields)}")
    checked = {k: check_field(fields[k], known, v, f"{name}.{k}") for k, v in params.items()}
    try:
        return cls(**checked)
    except TypeError as e:
        raise MeshError(f"filter {name!r}: {e}") from e



def check_parameters(step: typing.Any) -> dict:
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
    known, name = hints(cls), _name_of(step)
    return {f.name: check_field(f, known, getattr(step, f.name), f"{name}.{f.name}")
            for f in dataclasses.fields(cls) if f.init}


def apply(mesh: typing.Any, name: str, **params: typing.Any) -> typing.Any:
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

    def __init__(self, steps: typing.Iterable = ()):
        self.steps = []
        for s in steps:
            self.append(s)

    def append(self, step: typing.Any, **params: typing.Any) -> Chain:
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

    def __call__(self, mesh: typing.Any, progress: typing.Callable | None = None) -> typing.Any:
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

    def check(self, geometry: typing.Any) -> dict:
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

    def to_dict(self) -> dict:
        """The chain as plain data: ``{"filter": [{"name": ..., parameter: value, ...}, ...]}`` (None
        values left out), as written by :meth:`save`.

        Examples
        --------
        >>> import o3dheat.pipelines.filters as flt
        >>> flt.Chain([("colorize", {"attribute": "hks", "column": 3})]).to_dict()
        {'filter': [{'name': 'colorize', 'attribute': 'hks', 'column': 3, 'colormap': 'coolwarm', 'output': 'colors'}]}
        """
        return {"filter": [{"name": _name_of(s), **_plain(dataclasses.asdict(s))} for s in self.steps]}

    def save(self, path: PathLike) -> None:
        """Write the chain as TOML (atomically).

        Examples
        --------
        >>> import os, tempfile, o3dheat.pipelines.filters as flt
        >>> path = os.path.join(tempfile.mkdtemp(), "chain.toml")
        >>> flt.Chain([("scalar", {"kind": "height"})]).save(path)
        >>> print(open(path).read().splitlines()[2])
        [[filter]]
        """
        atomic_write_text(path, _to_toml(self.to_dict()))

    @classmethod
    def load(cls, path: PathLike) -> Chain:
        """Read a chain from a TOML file (``[[filter]]`` tables with ``name`` and parameters).

        Examples
        --------
        >>> import os, tempfile, o3dheat.pipelines.filters as flt
        >>> path = os.path.join(tempfile.mkdtemp(), "chain.toml")
        >>> flt.Chain([("scalar", {"kind": "height"}), ("hks", {"k": 20})]).save(path)
        >>> [type(step).__name__ for step in flt.Chain.load(path)]
        ['Scalar', 'Hks']
        """
        path = Path(path)
        if path.is_dir():
            raise MeshError(f"cannot read chain {path}: it is a folder")
        if not path.is_file():
            raise NoSuchFile(f"cannot read chain {path}: no such file")
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
def set_disk_cache(folder: PathLike | bool | None) -> None:
    """Also keep the filters' spectra on disk: a folder, True (``o3dheat.spectral.cache.default_cache_dir()``)
    or None (memory only, the default): :func:`o3dheat.spectral.cache.set_cache`.

    Examples
    --------
    >>> import tempfile, o3dheat.pipelines.filters as flt
    >>> flt.set_disk_cache(tempfile.mkdtemp()); flt.set_disk_cache(None)
    """
    spectral.set_cache(folder)


def shared_spectrum(V: typing.Any, F: typing.Any, k: int = 100, mass: str = "consistent",
                    cache: typing.Any = None) -> spectral.Spectrum:
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
    return spectral.shared_eigensolve(V, F, k=k, mass=mass, cache=cache)
