"""A chain of filters over many files: one task per file, in-process or on Dask, resumable.

Entry points: :func:`run` (a chain over files, a table of their status), :func:`expand` (the
inputs of paths and patterns), :func:`outputs` (their output files), :func:`summary` and
:func:`named_error` (reporting). ::

    table = o3dheat.pipelines.batch.run(chain, "scans/*.ply", "out/")
    o3dheat batch 'scans/*.ply' --out out/ -f scalar:kind=height -f heat_smooth:attribute=height

Notes
-----
Inputs are paths or glob patterns (expanded here: quote them in the shell; ``**`` recurses, into
each folder once: links to folders are followed, and a link loop ends), each pattern's matches
sorted by name; a file named twice (or by links) is run once. Patterns match no file of the output
folder, so that it may lie inside the inputs' tree (``'scans/**/*.ply' --out scans/out``). Each input gives
``OUT/<its stem>.ply`` (or ``.npz``), written atomically by :func:`o3dheat.io.write_geometry <o3dheat.io.meshes.write_geometry>`
(every vertex attribute, exactly): a file that exists is complete.

Refused before any work, with a :class:`~o3dheat.errors.MeshError` naming the culprits: a pattern that
matches no file, a missing input, two inputs whose outputs would have the same name (names are
compared without regard to case, for case-insensitive file systems), an output that would replace
an input, and an output folder holding the results of another chain.

Resume: the folder records its chain in ``OUT/o3dheat-batch.toml`` (a chain file:
``o3dheat apply IN OUT --chain OUT/o3dheat-batch.toml`` replays it). Running the same chain again
skips the outputs that exist (status "skipped") and computes the others, so an interrupted batch
resumes where it stopped and files that failed are retried; an output is skipped even when its
input changed since. ``overwrite=True`` (``--overwrite``) recomputes every output of the run and
records the chain: each output is then this run's result, or is removed when its file fails (an
earlier result is never passed off as this run's). Another chain: use another folder, or overwrite.

Failures: a file that cannot be read, is not a valid mesh, or on which a filter fails gets the
status "failed" and its error, writes nothing, and does not stop the others.

Execution (:mod:`o3dheat.pipelines.cluster`): on a local Dask cluster by default (one single-threaded worker
process per core), in-process with ``scheduler="sequential"``, on a running cluster by address or
``distributed.Client`` (its workers must see the input and output folders at the same paths). On
Dask the largest files start first; a script that starts a local cluster must be importable
(``if __name__ == "__main__":``), as Dask's worker processes import it (unguarded, the cluster is
refused before it starts: :func:`o3dheat.pipelines.cluster.unguarded_main`). BLAS runs on one thread in every mode, and o3dheat's own
threads (:mod:`o3dheat.parallel`: all cores in-process, one per Dask worker) do not change
results, so the outputs are identical bit for bit whatever the scheduler; they may differ in the
last bits from ``o3dheat apply`` when BLAS there runs on several threads.
"""

from __future__ import annotations

import logging
import os
import time
import traceback
import typing
from collections.abc import Sequence
from pathlib import Path

from o3dheat import checks, spectral
from o3dheat.errors import MeshError, SolverError
from o3dheat.io import read_geometry, write_geometry
from o3dheat.parallel import blas_one_thread, threads
from o3dheat.typing import PathLike

from ._inputs import MANIFEST, expand, outputs
from .cluster import progress_bar, session, task_error
from .filters import Chain

if typing.TYPE_CHECKING:  # annotations only: pandas is imported where the table is made
    import pandas as pd

__all__ = ["run", "expand", "outputs", "summary", "named_error", "COLUMNS", "STATUSES", "MANIFEST"]

log = logging.getLogger("o3dheat")

#: the columns of the table :func:`run` returns, one row per input file
COLUMNS = ["input", "output", "status", "seconds", "error"]
#: the values of its ``status`` column
STATUSES = ("done", "skipped", "failed")


# ------------------------------------------------------------------------------- one file
def _one(chain, src, dst, binary, single_threaded, name=None):
    """(status, seconds, error) of one file: read, run the chain, write atomically."""
    t0 = time.perf_counter()
    named = _Named(src if name is None else name)  # as the user gave it
    log.addFilter(named)  # the warnings of a file's work say which file they are about
    try:
        with blas_one_thread():  # BLAS results depend on its thread count; o3dheat's do not
            if single_threaded:
                with threads(1):
                    out = chain(read_geometry(src))
            else:
                out = chain(read_geometry(src))
            write_geometry(dst, out, binary=binary, overwrite=True)
        return "done", time.perf_counter() - t0, ""
    except Exception as e:  # a failing file is a result, not the end of the batch
        log.debug("%s failed: %s", src, traceback.format_exc())
        return "failed", time.perf_counter() - t0, _message(e)
    finally:  # the file's spectra serve no other file: free them before the next one's
        log.removeFilter(named)
        spectral.clear_cache()


class _Named(logging.Filter):
    """Prefixes o3dheat's log messages with a file's name (unless they already name it)."""

    def __init__(self, path):
        super().__init__()
        self.path, self.name_ = str(path), Path(path).name

    def filter(self, record):
        if self.name_ not in record.getMessage():
            record.msg, record.args = f"{self.path}: {record.getMessage()}", None
        return True


def _message(e):
    """An error as one line: o3dheat's own errors say what was wrong as they are, others with
    their type (:func:`o3dheat.pipelines.cluster.task_error`: a Dask worker's death with its usual cause)."""
    if isinstance(e, (MeshError, SolverError)):
        return " ".join(str(e).split()) or repr(e)
    return task_error(e)


# ------------------------------------------------------------------------------- the record
def _plain(x):
    """Tuples as lists, all the way down (a chain read back from TOML has lists)."""
    if isinstance(x, dict):
        return {k: _plain(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_plain(v) for v in x]
    return x


def _recorded(out_dir, chain):
    """Whether the folder's record holds this chain: True, False (another chain, or a record
    that cannot be read) or None (no record)."""
    path = out_dir / MANIFEST
    if not path.exists():
        return None
    try:
        return _plain(Chain.load(path).to_dict()) == _plain(chain.to_dict())
    except MeshError:
        return False


def _preflight(chain, paths, out_dir, overwrite, suffix):
    """(chain, inputs, outputs, record) after every check, before any work; writes nothing.
    ``record`` writes the folder and its chain record (called once the scheduler is reached, so
    that a bad scheduler address leaves no folder behind)."""
    if not isinstance(chain, Chain):
        chain = Chain(chain)
    if not len(chain):
        raise MeshError("no filter given: an empty chain")
    if not isinstance(out_dir, (str, os.PathLike)) or not str(out_dir).strip():
        raise MeshError(f"out_dir must be the output folder (a str or Path), got {out_dir!r}")
    out_dir = Path(out_dir)
    inputs = expand(paths, exclude=out_dir)  # its outputs are not inputs
    if out_dir.exists() and not out_dir.is_dir():
        raise MeshError(f"{out_dir} is a file: the output is a folder")
    dsts = outputs(inputs, out_dir, suffix)
    folders = [d for d in dsts if d.is_dir()]
    if folders:
        raise MeshError(f"{folders[0]} is a folder: it cannot be replaced by an output")
    same = _recorded(out_dir, chain) if out_dir.is_dir() else None
    existing = [d for d in dsts if d.exists()]
    if same is False and not overwrite:
        raise MeshError(f"{out_dir} holds the results of another chain ({out_dir / MANIFEST}): use another "
                        "folder, or --overwrite (overwrite=True) to recompute and replace them")
    if same is None and existing and not overwrite:
        names = ", ".join(d.name for d in existing[:3]) + (" ..." if len(existing) > 3 else "")
        raise MeshError(f"{out_dir} already has {names}, not written by a batch ({MANIFEST} is missing): "
                        "use another folder, or --overwrite (overwrite=True) to replace them")
    parent = next((p for p in out_dir.absolute().parents if p.exists()), None)
    if not out_dir.exists() and parent is not None and not (parent.is_dir() and os.access(parent, os.W_OK | os.X_OK)):
        raise MeshError(f"cannot create the output folder {out_dir}: {parent} is not a writable folder")

    def record():
        try:
            out_dir.mkdir(parents=True, exist_ok=True)
        except OSError as e:  # a file-system failure stays one, naming the folder
            raise type(e)(e.errno, f"cannot create the output folder {out_dir}: {e.strerror}") from None
        if not same:
            try:
                chain.save(out_dir / MANIFEST)
            except MeshError as e:
                raise MeshError(f"cannot record the chain in {out_dir / MANIFEST}: {e}") from None

    return chain, inputs, dsts, record


# ------------------------------------------------------------------------------- the batch
def run(chain: Chain | Sequence, paths: PathLike | Sequence[PathLike], out_dir: PathLike, scheduler: object = None,
        overwrite: bool = False, suffix: str = ".ply", binary: bool = True, progress: bool | None = None
        ) -> pd.DataFrame:
    """Run a chain of filters on many files, one task per file (see the module notes).

    Parameters
    ----------
    chain : o3dheat.pipelines.filters.Chain or a list of its steps
        The filters, applied in order to each file (a list is made a Chain; it is checked before any
        task runs).
    paths : str, Path or sequence of them
        Files or glob patterns (:func:`expand`).
    out_dir : str or Path
        Output folder (created); outputs are ``out_dir/<input stem><suffix>``.
    scheduler : None, "sequential", str or distributed.Client
        None: a local Dask cluster (one single-threaded worker per core), "sequential": in this
        process, "tcp://host:port": a running cluster, or a Client (:mod:`o3dheat.pipelines.cluster`).
    overwrite : bool
        False: outputs that exist are skipped (resume); True: every output is recomputed, and
        removed when its file fails.
    suffix : {".ply", ".npz"}
        The outputs' format: PLY (every vertex attribute a property) or numpy ``.npz``.
    binary : bool
        PLY only: binary (default) or ASCII.
    progress : bool, optional
        A progress bar on stderr (default: when stderr is a terminal).

    Returns
    -------
    pandas.DataFrame
        One row per input, in input order, columns :data:`COLUMNS`: ``input`` and ``output``
        (paths as str), ``status`` ("done", "skipped" or "failed"), ``seconds`` (the file's
        time: reading, filters, writing; 0 when skipped) and ``error`` ("" unless failed).

    Raises
    ------
    MeshError
        What is checked before any work (see the module notes); no file is written then.

    Examples
    --------
    >>> import os, tempfile, open3d as o3d, o3dheat
    >>> d = tempfile.mkdtemp()
    >>> for i in (1, 2):
    ...     o3dheat.io.write_mesh(os.path.join(d, f"s{i}.ply"), o3d.t.geometry.TriangleMesh.create_sphere(i, 8))
    >>> chain = o3dheat.pipelines.filters.Chain([("scalar", {"kind": "height"}),
    ...                                ("heat_smooth", {"attribute": "height", "k": 10, "scales": 2})])
    >>> table = o3dheat.pipelines.batch.run(chain, os.path.join(d, "*.ply"), os.path.join(d, "out"), scheduler="sequential")
    >>> table["status"].tolist(), [os.path.basename(p) for p in table["output"]]
    (['done', 'done'], ['s1.ply', 's2.ply'])
    >>> o3dheat.pipelines.batch.run(chain, os.path.join(d, "*.ply"), os.path.join(d, "out"), scheduler="sequential")["status"].tolist()
    ['skipped', 'skipped']
    """
    import pandas as pd  # here, not at the top: pandas costs ~0.4 s, which `import o3dheat` avoids

    for value, name in ((overwrite, "overwrite"), (binary, "binary"), (progress, "progress")):
        checks.flag(value, name, allow_none=name == "progress")
    chain, inputs, dsts, record = _preflight(chain, paths, out_dir, overwrite, suffix)
    rows = [[str(s), str(d), "skipped", 0.0, ""] for s, d in zip(inputs, dsts, strict=True)]
    todo = [i for i, d in enumerate(dsts) if overwrite or not d.exists()]
    src = [os.path.abspath(p) for p in inputs]  # workers may run elsewhere, in another folder
    dst = [os.path.abspath(p) for p in dsts]
    bar = progress_bar(len(todo), progress, unit="file")

    def done(i, result):
        status, seconds, error = result
        error = error.replace(src[i], str(inputs[i])).replace(dst[i], str(dsts[i]))  # the paths as given
        rows[i][2:] = [status, float(seconds), error]
        if status == "failed":
            log.warning("%s (failed: nothing written for it)", named_error(inputs[i], error))
            if overwrite and dsts[i].exists():  # an earlier result, not this run's
                try:
                    dsts[i].unlink()
                except OSError as e:
                    log.warning("could not remove %s (an earlier result): %s", dsts[i], e)
        if bar is not None:
            bar.update(1)

    try:
        with session(scheduler if todo else "sequential") as client:
            record()  # the scheduler is reached: now the folder
            if client is None:
                for i in todo:
                    done(i, _one(chain, src[i], dst[i], binary, False, str(inputs[i])))
            else:
                # here: distributed costs ~0.5 s at import, which `import o3dheat` avoids
                from distributed import as_completed

                sizes = {i: _size(src[i]) for i in todo}
                order = sorted(todo, key=lambda i: -sizes[i])  # the largest files first
                futures = {client.submit(_one, chain, src[i], dst[i], binary, True, str(inputs[i]), pure=False,
                                         priority=len(order) - r, key=f"o3dheat-batch-{i}-{os.urandom(4).hex()}"): i
                           for r, i in enumerate(order)}
                for fut in as_completed(list(futures)):
                    i = futures[fut]
                    try:
                        result = fut.result()
                    except Exception as e:  # the worker died (KilledWorker), was cancelled...
                        result = ("failed", 0.0, _message(e))
                    done(i, result)
    finally:
        if bar is not None:
            bar.close()
    return pd.DataFrame(rows, columns=COLUMNS)


def _size(path):
    try:
        return os.path.getsize(path)
    except OSError:
        return 0


def named_error(path: PathLike, error: str) -> str:
    """``"path: error"``, unless the error already starts with the path.

    Examples
    --------
    >>> from o3dheat.pipelines.batch import named_error
    >>> named_error("a.ply", "no faces"), named_error("a.ply", "a.ply: not a readable PLY file")
    ('a.ply: no faces', 'a.ply: not a readable PLY file')
    """
    path = str(path)
    return error if error.startswith(path) else f"{path}: {error}"


def summary(table: pd.DataFrame) -> str:
    """One line: how many files were done, skipped and failed, and the time they took.

    Examples
    --------
    >>> import pandas as pd
    >>> from o3dheat.pipelines.batch import summary, COLUMNS
    >>> summary(pd.DataFrame([["a.ply", "o/a.ply", "done", 1.5, ""], ["b.ply", "o/b.ply", "skipped", 0.0, ""]],
    ...                      columns=COLUMNS))
    '2 files: 1 done, 1 skipped (finished before), 0 failed; 1.5 s of work'
    """
    counts = {s: int((table["status"] == s).sum()) for s in STATUSES}
    return (f"{len(table)} file{'s' if len(table) != 1 else ''}: {counts['done']} done, "
            f"{counts['skipped']} skipped (finished before), {counts['failed']} failed; "
            f"{table['seconds'].sum():.1f} s of work")

