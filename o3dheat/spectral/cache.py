"""The caches of spectra: one in memory per process (:class:`SpectrumCache`), and signed files on disk.

Entry points: :func:`memoized`, :func:`memoized_has`, :func:`forget`, :func:`clear_cache`, :func:`set_cache` (the
process's cache, :data:`SPECTRA`: what :func:`o3dheat.spectral.spectrum.shared_eigensolve`, the
filters and the heat flow share), :func:`default_cache_dir`, :func:`cache_max_bytes`,
:func:`memory_cache_max_bytes`. The disk entries of :func:`o3dheat.spectral.spectrum.eigensolve`
(``cache=``) are keyed by :func:`spectrum_key`, read by :func:`load_entry` (and
:func:`entry_valid`) and written by :func:`save_entry`, as files signed by
:mod:`o3dheat.spectral._spectrum_files`.
"""

from __future__ import annotations

import hashlib
import logging
import os
import sys
from collections import OrderedDict
from collections.abc import Callable, Hashable
from pathlib import Path
from typing import Any

import numpy as np
import scipy.sparse as sp

from o3dheat.errors import MeshError
from o3dheat.memory import on_shortage
from o3dheat.typing import PathLike

from . import _spectrum_files

__all__ = ["SpectrumCache", "SPECTRA", "memoized", "memoized_has", "forget", "clear_cache", "set_cache", "default_cache_dir",
           "cache_max_bytes", "memory_cache_max_bytes"]

log = logging.getLogger("o3dheat")

_CACHE_VERSION = "3"  # 3: the sign rule of issue 30 (entries of 2 may have other signs)


def default_cache_dir() -> Path:
    r"""Folder of the on-disk spectrum cache: ``$O3DHEAT_CACHE``, else the platform's user cache
    folder (``$XDG_CACHE_HOME/o3dheat`` or ``~/.cache/o3dheat`` on Linux, ``~/Library/Caches/o3dheat``
    on macOS, ``%LOCALAPPDATA%\o3dheat\Cache`` on Windows).

    Returns
    -------
    pathlib.Path

    Examples
    --------
    >>> import o3dheat.spectral.cache as s
    >>> "o3dheat" in str(s.default_cache_dir())
    True
    """
    env = os.environ.get("O3DHEAT_CACHE")
    if env:
        return Path(env)
    if sys.platform == "win32" and os.environ.get("LOCALAPPDATA"):
        return Path(os.environ["LOCALAPPDATA"]) / "o3dheat" / "Cache"
    if sys.platform == "darwin":
        return Path.home() / "Library" / "Caches" / "o3dheat"
    xdg = os.environ.get("XDG_CACHE_HOME")
    return (Path(xdg) if xdg and os.path.isabs(xdg) else Path.home() / ".cache") / "o3dheat"


def cache_max_bytes() -> int:
    """Size budget of the on-disk cache: ``$O3DHEAT_CACHE_MAX_MB`` megabytes, default 2048. The least
    recently used spectra are deleted beyond it.

    Returns
    -------
    int
        Bytes.

    Examples
    --------
    >>> import os, o3dheat.spectral.cache as s
    >>> "O3DHEAT_CACHE_MAX_MB" in os.environ or s.cache_max_bytes() == 2048 * 2**20
    True
    """
    return _megabytes("O3DHEAT_CACHE_MAX_MB", 2048)


def _megabytes(variable, default):
    """Bytes of the environment variable ``variable`` (megabytes), else of ``default``."""
    try:
        value = float(os.environ.get(variable, str(default)))
        if not value >= 0:  # negative or NaN: a budget of nothing is 0
            raise ValueError
        return int(value * 2**20)
    except (ValueError, OverflowError):  # not a number, negative, or inf
        raise MeshError(f"{variable} must be a number of megabytes >= 0, got {os.environ[variable]!r}") from None




def memory_cache_max_bytes() -> int:
    """Size budget of the in-memory cache: ``$O3DHEAT_MEMORY_CACHE_MB`` megabytes, default 1024.
    Beyond it (or beyond 8 spectra) the least recently used spectra are dropped; the newest one is
    always kept, whatever its size (the filters of a chain share it).

    Returns
    -------
    int
        Bytes.

    Examples
    --------
    >>> import os, o3dheat.spectral.cache as s
    >>> "O3DHEAT_MEMORY_CACHE_MB" in os.environ or s.memory_cache_max_bytes() == 1024 * 2**20
    True
    """
    return _megabytes("O3DHEAT_MEMORY_CACHE_MB", 1024)


def _nbytes(value):
    """Bytes an object holds: its own ``nbytes`` where it tells (a factor, the operators), else
    those of the arrays and sparse matrices among its attributes."""
    own = getattr(value, "nbytes", None)
    if isinstance(own, (int, np.integer)) and not isinstance(own, bool):
        return int(own)
    total = 0
    for v in (vars(value).values() if hasattr(value, "__dict__") else [value]):
        if isinstance(v, np.ndarray):
            total += v.nbytes
        elif sp.issparse(v):
            total += sum(getattr(v, a).nbytes for a in ("data", "indices", "indptr") if hasattr(v, a))
    return total



class SpectrumCache:
    """The last results kept in memory, least recently used first out (at most ``max_entries`` and
    :func:`memory_cache_max_bytes`; the newest always kept, whatever its size: the filters of a
    chain share it), and the disk folder of :func:`o3dheat.spectral.spectrum.shared_eigensolve`.

    Parameters
    ----------
    max_entries : int
        Results kept at most.

    Attributes
    ----------
    entries : OrderedDict
        ``key -> (result, bytes)``, the least recently used first.
    disk : None, bool, str or Path
        The disk folder of :func:`~o3dheat.spectral.spectrum.shared_eigensolve`
        (:func:`set_cache`).

    Examples
    --------
    >>> from o3dheat.spectral.cache import SpectrumCache
    >>> c = SpectrumCache(max_entries=2)
    >>> [c.get(i, lambda: 10) for i in range(3)], len(c), 0 in c
    ([10, 10, 10], 2, False)
    """

    def __init__(self, max_entries: int = 8):
        self.entries: OrderedDict = OrderedDict()
        self.max_entries = max_entries
        self.disk = None

    def get(self, key: Hashable, compute: Callable[[], Any], room: int = 0) -> Any:
        """``compute()``, remembered under ``key``.

        Parameters
        ----------
        key : hashable
            What identifies the result (e.g. a hash of the geometry and the settings).
        compute : callable
            Called without arguments when ``key`` is not remembered.
        room : int
            Bytes ``compute`` is expected to need: the least recently used results are dropped
            first, until the budget has that much room (a factor of 10M vertices is not made
            while the cache keeps the last one).

        Returns
        -------
        The result of ``compute()``, now or from an earlier call.

        Examples
        --------
        >>> from o3dheat.spectral.cache import SpectrumCache
        >>> c = SpectrumCache()
        >>> c.get("a", lambda: 1), c.get("a", lambda: 2)
        (1, 1)
        """
        entries = self.entries
        if key in entries:
            entries.move_to_end(key)
            return entries[key][0]
        budget = memory_cache_max_bytes()
        while entries and room and sum(b for _, b in entries.values()) + room > budget:
            entries.popitem(last=False)
        value = compute()
        entries[key] = (value, _nbytes(value))
        while len(entries) > 1 and (len(entries) > self.max_entries or sum(b for _, b in entries.values()) > budget):
            entries.popitem(last=False)
        return value

    def clear(self) -> None:
        """Forget every result.

        Examples
        --------
        >>> from o3dheat.spectral.cache import SpectrumCache
        >>> c = SpectrumCache()
        >>> c.get("a", lambda: 1)
        1
        >>> c.clear(); len(c)
        0
        """
        self.entries.clear()

    def __contains__(self, key):
        return key in self.entries

    def __len__(self):
        return len(self.entries)


#: the process's cache: behind :func:`memoized`, :func:`set_cache` and :func:`clear_cache`
SPECTRA = SpectrumCache()


def set_cache(folder: PathLike | bool | None) -> None:
    """The disk folder used by :func:`o3dheat.spectral.spectrum.shared_eigensolve` (and the filters): a folder, True
    (:func:`default_cache_dir`) or None (memory only, the default).

    Parameters
    ----------
    folder : None, bool, str or Path
        The folder, True for :func:`default_cache_dir`, None for none.

    Examples
    --------
    >>> import tempfile, o3dheat.spectral.cache as c
    >>> c.set_cache(tempfile.mkdtemp()); c.set_cache(None)
    """
    SPECTRA.disk = folder


def clear_cache() -> None:
    """Forget the spectra kept in memory (the disk cache stays).

    Examples
    --------
    >>> import o3dheat.spectral.cache as c
    >>> c.clear_cache()
    """
    SPECTRA.clear()


def memoized(key: Hashable, compute: Callable[[], Any], room: int = 0) -> Any:
    """``compute()``, remembered under ``key`` among the last results (least recently used first
    out: at most 8 and :func:`memory_cache_max_bytes`, the newest always kept): the one in-memory
    cache of spectra, for meshes and for operators built elsewhere (:data:`SPECTRA`).

    Parameters
    ----------
    key : hashable
        What identifies the result (e.g. a hash of the geometry and the settings).
    compute : callable
        Called without arguments when ``key`` is not remembered.
    room : int
        Bytes ``compute`` is expected to need (see :meth:`SpectrumCache.get`).

    Returns
    -------
    The result of ``compute()``, now or from an earlier call.

    Examples
    --------
    >>> import o3dheat.spectral.cache as c
    >>> calls = []
    >>> c.memoized(("example", 1), lambda: calls.append(1) or 42), c.memoized(("example", 1), lambda: 0)
    (42, 42)
    >>> len(calls)
    1
    """
    return SPECTRA.get(key, compute, room)


def forget(match: Callable[[Hashable], bool]) -> int:
    """Drop the results whose key ``match`` accepts from the in-memory cache (their memory is given
    back once nothing else holds them); returns how many.

    Parameters
    ----------
    match : callable
        ``key -> bool``.

    Returns
    -------
    int

    Examples
    --------
    >>> import o3dheat.spectral.cache as c
    >>> c.memoized(("example", 2), lambda: 1)
    1
    >>> c.forget(lambda key: key == ("example", 2)), c.memoized_has(("example", 2))
    (1, False)
    """
    keys = [key for key in SPECTRA.entries if match(key)]
    for key in keys:
        del SPECTRA.entries[key]
    return len(keys)


def memoized_has(key: Hashable) -> bool:
    """Whether :func:`memoized` holds a result for ``key`` now.

    Parameters
    ----------
    key : hashable
        As for :func:`memoized`.

    Examples
    --------
    >>> import o3dheat.spectral.cache as c
    >>> c.memoized_has(("example", "absent"))
    False
    """
    return key in SPECTRA


on_shortage(clear_cache)  # a refused check (o3dheat.memory.check_memory) empties it first


# ---- the disk entries of eigensolve(cache=...) ------------------------------------------------

def disk_folder(cache):
    """The folder of ``eigensolve(cache=...)``: None for None or False, :func:`default_cache_dir`
    for True, else the path."""
    return None if cache in (None, False) else (default_cache_dir() if cache is True else Path(cache))


def spectrum_key(V, F, k, mass, method, tol=1e-8, sigma=None, seed=0, block=8):
    """Hash of everything that changes a spectrum: the geometry, k, the mass, and the solver
    settings (a tol=1e-2 answer must never be served to a tol=1e-10 call)."""
    h = hashlib.sha256()
    h.update(np.ascontiguousarray(V, dtype=np.float64).tobytes())
    h.update(np.ascontiguousarray(F, dtype=np.int64).tobytes())
    h.update(f"{V.shape}{F.shape}|{k}|{mass}|{method}|{float(tol)!r}|{sigma!r}|{seed}|{block}|"
             f"{_CACHE_VERSION}".encode())
    return h.hexdigest()[:32]


def load_entry(folder, key):
    """``(eigenvalues, eigenvectors, backend, sigma, residuals)`` of a signed entry, else None."""
    z = _spectrum_files.cache_load(folder, key)
    if z is None:
        return None
    try:
        return (z["eigenvalues"], z["eigenvectors"], str(z["backend"]), float(z["sigma"]), z["residuals"])
    except (KeyError, ValueError, TypeError) as e:
        log.warning("ignoring the cache entry %s (%s)", key, e)
        return None


def entry_valid(cached, r, k):
    """A signed entry (o3dheat's own write, :mod:`o3dheat.spectral._spectrum_files`) is used if it has the
    shapes of this problem, finite values and ascending eigenvalues (O(n k)): its residuals were
    checked when it was computed."""
    lam, X, _, _, res = cached
    if lam.shape != (k,) or X.shape != (r, k) or lam.dtype != np.float64 or X.dtype != np.float64:
        return False
    return bool(np.all(np.isfinite(lam)) and np.all(np.isfinite(X)) and np.all(np.diff(lam) >= 0)
                and lam[0] >= 0 and res.shape == (k,))


def save_entry(folder, key, lam, X, backend, sigma, res):
    """Write a signed entry (within :func:`cache_max_bytes`, the least recently used deleted)."""
    _spectrum_files.cache_save(folder, key, {"eigenvalues": lam, "eigenvectors": X, "backend": np.array(backend),
                                             "sigma": np.array(sigma), "residuals": res}, cache_max_bytes())
