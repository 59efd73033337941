"""Compiling o3dheat's loops with numba, once per installation: ``compiled(fn)``.

numba is imported only when a loop is first needed (``import o3dheat`` does not pay for it).
Compiled code is cached beside the module's file (``__pycache__``; numba falls back to a per-user
folder, or ``NUMBA_CACHE_DIR``, when that is not writable), so compiling (a few seconds) happens
once per installation and source version. Loops are compiled ``nogil``: o3dheat's threads
(:mod:`o3dheat.parallel`) run them side by side.
"""

from __future__ import annotations

import logging

__all__ = ["compiled", "any_compiled"]

log = logging.getLogger("o3dheat")
_COMPILED = {}


def compiled(fn):
    """The numba-compiled version of the plain Python function ``fn`` (compiled or loaded once).

    Examples
    --------
    >>> import numpy as np
    >>> from o3dheat._jit import compiled
    >>> def total(x):
    ...     s = 0.0
    ...     for v in x:
    ...         s += v
    ...     return s
    >>> compiled(total)(np.arange(4.0))
    6.0
    """
    key = (fn.__module__, fn.__qualname__)
    k = _COMPILED.get(key)
    if k is None:
        from numba import njit

        try:
            k = njit(cache=True, nogil=True)(fn)
        except RuntimeError as e:  # no writable cache location at all: compile in every process
            log.warning("o3dheat's compiled loops cannot be cached (%s): they are compiled again in each "
                        "process; set NUMBA_CACHE_DIR to a writable folder", e)
            k = njit(nogil=True)(fn)
        _COMPILED[key] = k
    return k


def any_compiled(module):
    """Whether this process compiled (rather than loaded from the cache) a loop of ``module`` or of
    a module inside it (``"o3dheat.topology"`` covers the whole stage).

    Examples
    --------
    >>> from o3dheat._jit import any_compiled
    >>> isinstance(any_compiled("o3dheat.topology"), bool)
    True
    """
    return any(sum(k.stats.cache_misses.values()) > 0 for (mod, _), k in _COMPILED.items()
               if (mod == module or mod.startswith(module + ".")) and hasattr(k, "stats"))
