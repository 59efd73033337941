"""Argument checks shared by every module: :func:`field`, :func:`values`, :func:`count`,
:func:`times`, :func:`tolerance`, :func:`vertex_set` (what users pass as fields, counts, times).

Fields may come as numpy arrays, Python lists or Open3D tensors (``mesh.vertex["f"]``, or any
object with a ``numpy()`` method); :func:`values` turns them into numpy arrays before the
module's own shape checks. Counts (scales, iterations, steps, level sets) are positive integers
with an upper bound, so an absurd request (``count=10**9``) is refused at once instead of being
attempted.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

from o3dheat.errors import MeshError

if TYPE_CHECKING:
    from numpy.typing import ArrayLike

    from o3dheat.typing import FieldLike, TimesLike

__all__ = ["values", "field", "flag", "count", "times", "tolerance", "vertex_set"]


def values(x: Any) -> Any:
    """``x`` as something :func:`numpy.asarray` reads: an Open3D tensor (or any object with a
    ``numpy()`` method) becomes its numpy array; anything else is returned as is.

    Examples
    --------
    >>> import numpy as np, open3d as o3d
    >>> from o3dheat.checks import values
    >>> values(o3d.core.Tensor(np.arange(3.0))).tolist(), values([1, 2])
    ([0.0, 1.0, 2.0], [1, 2])
    """
    to_numpy = getattr(x, "numpy", None)
    if callable(to_numpy) and not isinstance(x, np.ndarray):
        try:
            return np.asarray(to_numpy())
        except Exception as e:  # e.g. a tensor on a device numpy cannot read
            raise MeshError(f"cannot read the {type(x).__name__} as numbers ({e}): pass a numpy array") from e
    return x


def field(f: FieldLike, n: int | None = None, name: str = "f", ndim: int | tuple[int, ...] = (1, 2)) -> np.ndarray:
    """A per-vertex field as a float64 array, checked: numeric (bool included), ``n`` rows (one
    value per vertex, when ``n`` is given), ``ndim`` in the allowed ones, every value finite. The one
    field check of every module, with one message style.

    Examples
    --------
    >>> import numpy as np
    >>> from o3dheat.checks import field
    >>> field([1, 2, 3], 3).dtype.name
    'float64'
    >>> field([1.0, np.nan, 3.0], 3)
    Traceback (most recent call last):
    ...
    o3dheat.errors.MeshError: f has 1 NaN or infinite values (first at vertex 1)
    """
    arr = np.asarray(values(f))
    if arr.dtype == object or not (np.issubdtype(arr.dtype, np.number) or arr.dtype == bool):
        raise MeshError(f"{name} must be numeric, got dtype {arr.dtype}")
    if np.issubdtype(arr.dtype, np.complexfloating):
        raise MeshError(f"{name} must be real, got dtype {arr.dtype}")
    arr = arr.astype(np.float64)
    if arr.ndim not in ndim or (n is not None and len(arr) != n):
        rows = "n" if n is None else n
        shapes = " or ".join({1: f"({rows},)", 2: f"({rows}, c)", 3: f"({rows}, c, d)"}[d] for d in ndim)
        raise MeshError(f"{name} must have shape {shapes} (one value per vertex), got {arr.shape}")
    bad = ~np.isfinite(arr)
    if bad.any():
        first = int(np.flatnonzero(bad.reshape(len(arr), -1).any(axis=1))[0])
        raise MeshError(f"{name} has {int(bad.sum())} NaN or infinite values (first at vertex {first})")
    return arr


def flag(x: Any, name: str, allow_none: bool = False) -> bool | None:
    """``x`` as a bool (True, False, or numpy's), or a :class:`~o3dheat.errors.MeshError` naming
    ``name``: a string such as ``"no"`` is truthy and would say the opposite of what it reads.

    Examples
    --------
    >>> from o3dheat.checks import flag
    >>> flag(True, "overwrite")
    True
    >>> flag("no", "overwrite")
    Traceback (most recent call last):
    ...
    o3dheat.errors.MeshError: overwrite must be True or False, got 'no' (str)
    """
    if x is None and allow_none:
        return None
    if not isinstance(x, (bool, np.bool_)):
        raise MeshError(f"{name} must be True or False{' (or None)' if allow_none else ''}, got {x!r} "
                        f"({type(x).__name__})")
    return bool(x)


def count(x: Any, name: str, minimum: int = 1, maximum: int = 1_000_000) -> int:
    """``x`` as an int in ``[minimum, maximum]``, or a :class:`~o3dheat.errors.MeshError` naming ``name``.

    Examples
    --------
    >>> from o3dheat.checks import count
    >>> count(10, "scales")
    10
    >>> count(10**9, "scales", maximum=100_000)
    Traceback (most recent call last):
    ...
    o3dheat.errors.MeshError: scales must be an integer from 1 to 100000, got 1000000000
    """
    if isinstance(x, bool) or not isinstance(x, (int, np.integer)) or not minimum <= x <= maximum:
        raise MeshError(f"{name} must be an integer from {minimum} to {maximum}, got {x!r}")
    return int(x)


def times(t: TimesLike) -> float | np.ndarray:
    """Times as a float64 scalar or a non-empty 1-D array: numbers (not text: ``"0.1"`` is refused,
    not parsed), finite and >= 0 (the backward heat equation is ill-posed).

    Examples
    --------
    >>> from o3dheat.checks import times
    >>> times([0.1, 1]).tolist()
    [0.1, 1.0]
    >>> times([])
    Traceback (most recent call last):
    ...
    o3dheat.errors.MeshError: t is empty: give at least one time
    """
    raw = np.asarray(values(t)) if not isinstance(t, (str, bytes)) else np.asarray(t)
    if raw.dtype.kind in "USOV" and raw.size:  # text, bytes, objects: not times
        raise MeshError(f"t must be a number or a 1-D array of times, got {t!r}")
    try:
        t_arr = raw.astype(np.float64)
    except (TypeError, ValueError):
        raise MeshError(f"t must be a number or a 1-D array of times, got {t!r}") from None
    if t_arr.ndim > 1:
        raise MeshError(f"t must be a number or a 1-D array of times, got shape {t_arr.shape}")
    if t_arr.size == 0:
        raise MeshError("t is empty: give at least one time")
    if not np.all(np.isfinite(t_arr)) or np.any(t_arr < 0):
        raise MeshError(f"times must be finite and >= 0 (the backward heat equation is ill-posed), got {t}")
    return t_arr


def tolerance(tol: Any, name: str = "tol") -> float:
    """A relative tolerance: a real number in (0, 1).

    Examples
    --------
    >>> from o3dheat.checks import tolerance
    >>> tolerance(1e-8)
    1e-08
    >>> tolerance(0)
    Traceback (most recent call last):
    ...
    o3dheat.errors.MeshError: tol must be a number in (0, 1), got 0
    """
    if isinstance(tol, bool) or not isinstance(tol, (int, float, np.integer, np.floating)) \
            or not (np.isfinite(tol) and 0 < tol < 1):
        raise MeshError(f"{name} must be a number in (0, 1), got {tol!r}")
    return float(tol)


def vertex_set(A: ArrayLike, n: int, name: str = "A") -> np.ndarray:
    """A vertex set (indices, repeats allowed, or a boolean mask) as a boolean mask of length n.

    Examples
    --------
    >>> from o3dheat.checks import vertex_set
    >>> vertex_set([0, 2, 2], 4).tolist()
    [True, False, True, False]
    """
    arr = np.asarray(values(A))
    if arr.dtype == bool:
        if arr.shape != (n,):
            raise MeshError(f"a boolean vertex mask must have shape ({n},), got {arr.shape}")
        return arr.copy()
    if arr.size == 0:
        return np.zeros(n, bool)
    if not np.issubdtype(arr.dtype, np.integer) or arr.ndim != 1:
        raise MeshError(f"{name} must be a 1-D sequence of vertex indices or a boolean mask over the vertices")
    if arr.min() < 0 or arr.max() >= n:
        raise MeshError(f"vertex index out of range [0, {n - 1}] in {name}")
    mask = np.zeros(n, bool)
    mask[arr] = True
    return mask
