"""fast-simplification's quadric decimation, one call at a time, large meshes in a child process.

fast-simplification keeps its mesh in module-wide C++ vectors. Two threads at once crashed the
process or swapped meshes, hence one lock. The vectors also keep their capacity after a call:
about 300 bytes per input face stay allocated until the process exits (measured: 613 bytes per
vertex after a 4M-face ellipsoid; 6 GB after a 20M-face scan), and ``malloc_trim`` cannot return
them because they are still in use. Above :data:`CHILD_FACES` faces the call runs in a forked
child (copy-on-write: the mesh is not copied), which sends back the small result through a pipe and
exits, its memory with it. Where ``os.fork`` is missing (Windows) the call runs in the process.
"""

from __future__ import annotations

import os
import pickle
import signal
import threading
import warnings

import numpy as np

from o3dheat.errors import OutOfMemory, SolverError

__all__ = ["CHILD_FACES", "simplify"]

#: meshes with more faces are decimated in a forked child (below, the capacity kept, at most about
#: 300 MB, costs less than the fork's milliseconds)
CHILD_FACES = 1_000_000

_LOCK = threading.Lock()


def simplify(V: np.ndarray, F: np.ndarray, reduction: float, vertex_map: bool) -> tuple:
    """``(V2, F2, vmap)``: ``fast_simplification.simplify`` at ``target_reduction=reduction``, and
    with ``vertex_map`` its collapse replay's map (else ``vmap`` is None).

    Raises :class:`~o3dheat.errors.OutOfMemory` when the child process was killed (the system's
    out-of-memory killer), :class:`~o3dheat.errors.SolverError` when it failed otherwise.

    Examples
    --------
    >>> import numpy as np, open3d as o3d
    >>> from o3dheat.geometry._simplify import simplify
    >>> m = o3d.geometry.TriangleMesh.create_sphere(1.0, 20)
    >>> V2, F2, vmap = simplify(np.asarray(m.vertices), np.asarray(m.triangles), 0.5, True)
    >>> len(F2) <= len(m.triangles) // 2 + 2, len(vmap) == len(m.vertices)
    (True, True)
    """
    with _LOCK:
        if len(F) > CHILD_FACES and hasattr(os, "fork"):
            return _in_child(V, F, reduction, vertex_map)
        return _simplify(V, F, reduction, vertex_map)


def _simplify(V, F, reduction, vertex_map):
    import fast_simplification

    F32 = F.astype(np.int32)
    V2, F2, *collapses = fast_simplification.simplify(V, F32, target_reduction=reduction,
                                                      return_collapses=vertex_map)
    vmap = None
    if vertex_map:
        V2, F2, vmap = fast_simplification.replay_simplification(V, F32, collapses[0])
    return V2, F2, vmap


def _in_child(V, F, reduction, vertex_map):
    import fast_simplification  # noqa: F401 - loaded here, so the child does not import

    r, w = os.pipe()
    with warnings.catch_warnings():  # Python 3.12 warns of fork in a threaded process: the child
        warnings.simplefilter("ignore", DeprecationWarning)  # runs numpy and C++ only, then exits
        pid = os.fork()
    if pid == 0:  # the child: decimate, send, exit without the parent's clean-up
        code = 0
        try:
            os.close(r)
            try:
                out = ("ok", tuple(None if a is None else np.asarray(a) for a in _simplify(V, F, reduction, vertex_map)))
            except BaseException as e:  # noqa: BLE001 - sent to the parent, which raises it
                out = ("error", f"{type(e).__name__}: {e}")
            with os.fdopen(w, "wb") as fh:
                pickle.dump(out, fh, protocol=pickle.HIGHEST_PROTOCOL)
        except BaseException:  # noqa: BLE001 - the parent sees the exit code
            code = 1
        finally:
            os._exit(code)
    os.close(w)
    with os.fdopen(r, "rb") as fh:
        try:
            out = pickle.load(fh)
        except (EOFError, pickle.UnpicklingError):
            out = None
    _, status = os.waitpid(pid, 0)
    if out is None:
        code = os.waitstatus_to_exitcode(status)
        if code == -signal.SIGKILL:
            raise OutOfMemory(f"the decimation of {len(F):,} faces was killed (signal 9: the system ran out of "
                              "memory): decimate a part at a time, or use a machine with more memory")
        raise SolverError(f"the decimation of {len(F):,} faces failed in its process (exit code {code})")
    if out[0] == "error":
        raise SolverError(f"fast-simplification failed on {len(F):,} faces: {out[1]}")
    return out[1]
