"""Filter parameters: their types and bounds, the one check of a value, the one reading of command-line text.

Entry points: :func:`param` (a parameter with :class:`Limits`), :class:`OneOf` (choices read when a
value is checked), :func:`check_value` (a value against an annotation), :func:`parse_value` (text
of ``-f NAME:key=value`` for an annotation), :func:`hints` (a filter's resolved annotations),
:class:`Parameter` (what :func:`o3dheat.pipelines.filters.describe` lists). All reachable from
:mod:`o3dheat.pipelines.filters`.
"""

from __future__ import annotations

import dataclasses
import re
import types
import typing

import numpy as np

from o3dheat.errors import MeshError


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


def doc_params(doc: str | None) -> dict:
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


def plain_text(text: str) -> str:
    r"""The reStructuredText of a docstring as plain one-line text: ````literal```` and ```x``` lose their
    backticks, roles keep their text (``:func:`~a.b` `` -> ``b``, ``:class:`T <a.T>` `` -> ``T``),
    a trailing ``::`` becomes ``:``, and lines are joined.

    Examples
    --------
    >>> from o3dheat.pipelines.filters import plain_text
    >>> plain_text("Smooth ``f`` with\n    :func:`~o3dheat.spectral.kernel.smooth` (see :class:`HeatKernel <o3dheat.spectral.kernel.HeatKernel>`)::")
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


class OneOf:
    """A filter parameter's choices that are defined elsewhere and read when a value is checked,
    never copied: annotate the field ``typing.Annotated[str, OneOf(lambda: CHOICES)]``.

    The built-in filters' ``variant`` is ``Annotated[str, OneOf(lambda: o3dheat.spectral.variants.VARIANTS)]``:
    a variant added to :data:`o3dheat.spectral.variants.VARIANTS` is accepted at once, and :func:`~o3dheat.pipelines.filters.describe`
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

    def __init__(self, choices: typing.Callable[[], typing.Iterable]):
        if not callable(choices):
            raise TypeError("OneOf takes a callable returning the choices (read when a value is checked)")
        self._choices = choices

    def choices(self) -> tuple:
        """The allowed values now, as a tuple.

        Examples
        --------
        >>> from o3dheat.pipelines.filters import OneOf
        >>> OneOf(lambda: ("a", "b")).choices()
        ('a', 'b')
        """
        return tuple(self._choices())

    @staticmethod
    def of(tp: typing.Any) -> OneOf | None:
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


LIMITS = "o3dheat.limits"  # the key of a dataclass field's metadata that holds its Limits


@dataclasses.dataclass(frozen=True)
class Limits:
    """The bounds of a filter parameter, declared with it (:func:`param`) and checked with its type
    wherever a value comes in: :func:`~o3dheat.pipelines.filters.get` (so :meth:`~o3dheat.pipelines.filters.Chain.load`, the command's ``-f``),
    :meth:`~o3dheat.pipelines.filters.Chain.append` and :meth:`~o3dheat.pipelines.filters.Chain.check` (instances made directly), and the built-in
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

    def check(self, value: typing.Any, where: str) -> None:
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
    def of(field: dataclasses.Field) -> Limits | None:
        """The :class:`Limits` a dataclass field was declared with (:func:`param`), else None.

        Examples
        --------
        >>> import dataclasses, o3dheat.pipelines.filters as flt
        >>> [str(flt.Limits.of(f)) for f in dataclasses.fields(flt.get("hks")) if f.name == "k"]
        ['>= 1']
        """
        return field.metadata.get(LIMITS) if field.metadata else None


def param(default: typing.Any = None, **limits: float | int | None) -> dataclasses.Field:
    """A filter parameter with bounds: ``delta: float | None = param(None, ge=0)``, a dataclass field
    whose metadata holds its :class:`Limits` (``ge``, ``gt``, ``le``, ``lt``, ``min_len``,
    ``max_len``), listed by :func:`~o3dheat.pipelines.filters.describe` and checked before any work (see :class:`Limits`).

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
    return dataclasses.field(default=default, metadata={LIMITS: Limits(**limits)})


def type_text(tp: typing.Any) -> str:
    """An annotation as :func:`o3dheat.pipelines.filters.describe` shows it (``int``,
    ``Literal['a', 'b']`` for a :class:`OneOf`, ``tuple[float, ...] | None``)."""
    if tp in (int, float, str, bool):
        return tp.__name__
    one_of = OneOf.of(tp)
    if one_of is not None:
        return "Literal[" + ", ".join(map(repr, one_of.choices())) + "]"
    return str(tp).replace("typing.", "")


def hints(cls: type) -> dict:
    """The annotations of a filter class's fields: ``{name: type}``, each resolved in the module of
    the class that declares it (a plugin's subclass of a built-in filter keeps the built-in's types).

    Parameters
    ----------
    cls : type
        A filter dataclass.

    Raises
    ------
    MeshError
        An annotation that cannot be resolved (a name defined inside a function, or never
        imported, in a module with ``from __future__ import annotations``): its parameters could
        not be checked, so the filter is refused, naming it and the error.

    Examples
    --------
    >>> import dataclasses
    >>> from o3dheat.pipelines._params import hints
    >>> @dataclasses.dataclass(frozen=True)
    ... class Lost:
    ...     size: "Undefined" = 1
    >>> hints(Lost)
    Traceback (most recent call last):
    ...
    o3dheat.errors.MeshError: filter class Lost: the annotations of its parameters cannot be resolved (NameError: name 'Undefined' is not defined): define the names they use at the module level of the class
    """
    try:
        return typing.get_type_hints(cls, include_extras=True)
    except Exception as e:
        raise MeshError(f"filter class {cls.__qualname__}: the annotations of its parameters cannot be resolved "
                        f"({type(e).__name__}: {e}): define the names they use at the module level of the "
                        "class") from e


def check_value(tp: typing.Any, value: typing.Any, where: str) -> typing.Any:
    """``value`` checked (and converted where lossless) against the annotation ``tp``; a MeshError
    naming ``where`` (``filter.parameter``) otherwise."""
    origin = typing.get_origin(tp)
    args = typing.get_args(tp)
    if tp is typing.Any:
        return value
    if origin is typing.Annotated:
        value = check_value(args[0], value, where)
        one_of = OneOf.of(tp)
        if one_of is not None and value not in one_of.choices():
            raise MeshError(f"{where} must be one of {', '.join(map(repr, one_of.choices()))}, got {value!r}")
        return value
    if origin is typing.Union or origin is types.UnionType:
        if value is None and type(None) in args:
            return None
        errors = []
        for a in args:
            if a is type(None):
                continue
            try:
                return check_value(a, value, where)
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
        return tuple(check_value(item, v, where) for v in value)
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


def parse_value(text: str, tp: typing.Any) -> typing.Any:
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
    if origin is typing.Union or origin is types.UnionType:
        if low in ("none", "null", "") and type(None) in args:
            return None
        for a in args:
            if a is type(None):
                continue
            try:
                return parse_value(text, a)
            except (ValueError, MeshError):
                continue
        raise MeshError(f"cannot read {text!r} as {type_text(tp)}")
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


def check_field(field: dataclasses.Field, known: dict, value: typing.Any, where: str) -> typing.Any:
    """A parameter's value checked against its annotation in ``known`` (:func:`hints`;
    :func:`check_value`), then its bounds (:class:`Limits`)."""
    value = check_value(known.get(field.name, typing.Any), value, where)
    limits = Limits.of(field)
    if limits is not None:
        limits.check(value, where)
    return value

