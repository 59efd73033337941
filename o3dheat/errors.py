"""The o3dheat exception family: :class:`MeshError` (bad input; :class:`NoSuchFile`), :class:`SolverError`
(a computation failed; :class:`ConvergenceError`, :class:`OutOfMemory`).

Every error raised on purpose by o3dheat is a :class:`MeshError` (a ``ValueError``) or a
:class:`SolverError` (a ``RuntimeError``; :class:`ConvergenceError` and
:class:`OutOfMemory` are kinds of it), with a message that says what was wrong and
what to do about it.
"""

__all__ = ["MeshError", "NoSuchFile", "SolverError", "ConvergenceError", "OutOfMemory"]


class MeshError(ValueError):
    """Bad input: a mesh, a field, a time or a parameter that o3dheat cannot work with. A
    ``ValueError``.

    Examples
    --------
    >>> import numpy as np, o3dheat
    >>> try:
    ...     o3dheat.as_arrays((np.zeros((0, 3)), np.zeros((0, 3), int)))
    ... except o3dheat.MeshError as e:
    ...     print("empty" in str(e))
    True
    """


class NoSuchFile(MeshError, FileNotFoundError):
    """A path given as input that names no file: a bad argument (a :class:`MeshError`) and the file
    system's answer (a ``FileNotFoundError``, so an ``OSError``), caught by either. Raised where
    o3dheat checks its inputs before reading them (mesh files, chain files, batch inputs); a file
    that exists but cannot be read gives the file system's own ``OSError``.

    Examples
    --------
    >>> import o3dheat
    >>> from o3dheat.errors import NoSuchFile
    >>> try:
    ...     o3dheat.io.read_mesh("/no/such/mesh.ply")
    ... except FileNotFoundError as e:
    ...     print(type(e).__name__, isinstance(e, o3dheat.MeshError), e)
    NoSuchFile True no such file: /no/such/mesh.ply
    """


class SolverError(RuntimeError):
    """A numerical solver failed (factorization, eigensolver, time stepping). A ``RuntimeError``.

    Examples
    --------
    >>> import o3dheat
    >>> issubclass(o3dheat.SolverError, RuntimeError)
    True
    """


class ConvergenceError(SolverError):
    """An iterative eigensolver stopped without converging (or could not run on so small a
    problem); :func:`o3dheat.eigensolve <o3dheat.spectral.spectrum.eigensolve>` then falls back to the next method.

    Examples
    --------
    >>> import o3dheat
    >>> issubclass(o3dheat.errors.ConvergenceError, o3dheat.SolverError)
    True
    """


class OutOfMemory(SolverError):
    """The work does not fit in the memory this process may use (estimated before, or reported by
    CHOLMOD): no other backend is tried, since it would need as much and may crash the process.

    Examples
    --------
    >>> import o3dheat, o3dheat.memory as mm
    >>> from o3dheat.errors import OutOfMemory
    >>> issubclass(OutOfMemory, o3dheat.SolverError)
    True
    >>> try:
    ...     mm.check_memory(2**70, "this eigensolve", "use a smaller mesh")    # 1 ZiB
    ... except OutOfMemory as e:
    ...     print(str(e).split(",")[0])
    this eigensolve needs about 1099511627776.00 GiB
    """
