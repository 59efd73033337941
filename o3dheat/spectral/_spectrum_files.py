"""Spectra on disk: the signed entries of the spectrum cache, and the ``.npz`` files of :meth:`o3dheat.Spectrum.save <o3dheat.spectral.spectrum.Spectrum.save>`.

Entry points: :func:`cache_load`, :func:`cache_save`, :func:`prune` (the signed entries read and
written by :mod:`o3dheat.spectral.cache`), :func:`spectrum_arrays`, :func:`read_spectrum` and
:func:`check_loaded` (the self-contained files of :meth:`~o3dheat.spectral.spectrum.Spectrum.save` and
:meth:`~o3dheat.spectral.spectrum.Spectrum.load`); written with :func:`o3dheat.io.atomic_write <o3dheat.io.files.atomic_write>`.

Notes
-----
Only o3dheat's own writes are read back from a cache folder: every entry carries a keyed BLAKE2b
signature of its name and arrays, made with a secret kept in the folder (``.o3dheat-key``, 32
random bytes, readable by its owner only, created once). A file placed in the folder by another
tool or by hand, edited, renamed to another key or copied from another folder has no matching
signature and is recomputed, never trusted. This guards against accidents and foreign files, not
against someone who can read the key (they can write the folder anyway). Pruning deletes only
o3dheat's own names (``spectrum-<32 hex digits>.npz`` and its writers' temporary files).
"""

from __future__ import annotations

import hashlib
import hmac
import io
import logging
import os
import re
import stat
import tempfile
import time
import zipfile
from pathlib import Path

import numpy as np
import scipy.sparse as sp

from o3dheat.errors import MeshError
from o3dheat.io import atomic_write, read_regular

from . import fem
from ._solvers import residuals

log = logging.getLogger("o3dheat")

KEY_FILE = ".o3dheat-key"
ENTRY = re.compile(r"spectrum-[0-9a-f]{32}\.npz")
PARTIAL = re.compile(r"spectrum-[A-Za-z0-9_]+\.npz\.tmp")  # older versions' temporary files


def entry_path(folder, key):
    """The cache entry of ``key`` (a 32-digit hex string) in ``folder``."""
    return Path(folder) / f"spectrum-{key}.npz"


def _writable_by_others(st):
    """Whether a folder's mode lets other users replace what is in it (group or others may write,
    without the sticky bit that keeps them to their own files)."""
    return bool(st.st_mode & 0o022) and not st.st_mode & stat.S_ISVTX


def _read_key(path):
    """The key file's bytes, or None (with a warning) when it is not a regular file of this user
    that no one else may read or write, as ssh treats its keys: a key another user could write
    would let them sign entries o3dheat then serves."""
    fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK | getattr(os, "O_NOFOLLOW", 0))
    try:
        st = os.fstat(fd)
        why = ("not a regular file" if not stat.S_ISREG(st.st_mode) else
               f"owned by another user (uid {st.st_uid})" if st.st_uid != os.geteuid() else
               f"readable or writable by others (mode {stat.S_IMODE(st.st_mode):o})" if st.st_mode & 0o077 else "")
        if why:
            log.warning("ignoring the cache key %s: %s; the folder's entries are not trusted (remove the key, "
                        "and keep the cache folder to yourself)", path, why)
            return None
        return os.read(fd, 33)
    finally:
        os.close(fd)


def folder_key(folder, create):
    """The folder's secret (bytes), made on first use when ``create``; None when it has none or
    cannot be read, or when it or the folder is open to other users (with a warning). Made by a
    hard link of a complete file: a concurrent reader never sees a partial key."""
    path = Path(folder) / KEY_FILE
    try:
        if _writable_by_others(os.stat(folder)):
            log.warning("not using the cache folder %s: other users may write in it (mode %o); use a folder "
                        "of your own (chmod go-w)", folder, stat.S_IMODE(os.stat(folder).st_mode))
            return None
    except OSError:
        return None
    for _ in range(2):
        try:
            secret = _read_key(path)
            if secret is None:
                return None
            if len(secret) == 32:
                return secret
            log.warning("ignoring the malformed cache key %s: the folder's entries are not trusted", path)
            return None
        except FileNotFoundError:
            if not create:
                return None
        except OSError:
            return None
        fd, tmp = tempfile.mkstemp(dir=folder, prefix=".o3dheat-key-")
        try:
            with os.fdopen(fd, "wb") as fh:
                fh.write(os.urandom(32))
            os.chmod(tmp, 0o600)
            os.link(tmp, path)  # fails if another writer made it first: then its key is read
        except FileExistsError:
            pass
        except OSError:
            return None
        finally:
            os.unlink(tmp)
    return None


def signature(secret, key, arrays):
    """Keyed BLAKE2b of the entry's name and its arrays (names, dtypes, shapes and bytes)."""
    h = hashlib.blake2b(key=secret, digest_size=32)
    h.update(key.encode())
    for name in sorted(arrays):
        a = np.ascontiguousarray(arrays[name])
        h.update(f"|{name}|{a.dtype.str}|{a.shape}|".encode())
        if a.size:
            h.update(memoryview(a).cast("B"))
    return np.frombuffer(h.digest(), dtype=np.uint8)


def cache_load(folder, key):
    """The arrays of the entry ``key`` if it is o3dheat's own (its signature matches); None when
    it is absent, unreadable or foreign (with a warning naming it)."""
    path = entry_path(folder, key)
    if not path.exists():
        return None
    try:
        data = read_regular(path, "cache entry")  # a FIFO or a link to a device: refused, not waited on
        with np.load(io.BytesIO(data), allow_pickle=False) as z:
            arrays = {name: z[name] for name in z.files}
    except Exception as e:  # a corrupt cache file is ignored, never fatal
        log.warning("ignoring unreadable cache file %s (%s)", path, e)
        return None
    stored = arrays.pop("signature", None)
    secret = folder_key(folder, create=False)
    if stored is None or secret is None or not hmac.compare_digest(
            stored.tobytes(), signature(secret, key, arrays).tobytes()):
        log.warning("the cached spectrum %s is not o3dheat's own write for this key (tampered or corrupt: "
                    "its signature does not match): recomputing", path.name)
        return None
    try:
        os.utime(path)  # used now, and ours: the last to be pruned
    except OSError:
        pass
    return arrays


def cache_save(folder, key, arrays, budget):
    """Store ``arrays`` signed under ``key``, then prune the folder to ``budget`` bytes; a folder
    that cannot be written gives a warning, never an error."""
    folder = Path(folder)
    try:
        folder.mkdir(parents=True, exist_ok=True)
        secret = folder_key(folder, create=True)
        if secret is None:
            raise OSError(f"no readable key {KEY_FILE}")
        signed = {**arrays, "signature": signature(secret, key, arrays)}
        atomic_write(entry_path(folder, key), lambda fh: np.savez(fh, **signed))
        prune(folder, budget, keep=entry_path(folder, key))
    except (OSError, MeshError) as e:  # atomic_write names an unwritable folder with a MeshError
        log.warning("could not write the spectrum cache in %s (%s)", folder, e)


def _ours(path):
    """Whether ``path`` is an o3dheat cache entry: its name, and the members o3dheat writes."""
    if not ENTRY.fullmatch(path.name):
        return False
    try:
        with zipfile.ZipFile(path) as z:
            return "eigenvectors.npy" in z.namelist()
    except (OSError, zipfile.BadZipFile):
        return True  # o3dheat's name, unreadable content: a broken write of ours


def prune(folder, budget, keep=None, stale_after=3600.0):
    """Delete temporary files left by interrupted writes (older than an hour: a live writer is
    faster), then the least recently used entries until o3dheat's entries hold at most ``budget``
    bytes (``keep``, the entry just written, stays even when it alone exceeds the budget). Files
    with other names are never touched."""
    folder = Path(folder)
    now = time.time()
    files = []
    for f in folder.glob("spectrum-*"):
        try:
            st = f.stat()
        except OSError:
            continue
        if PARTIAL.fullmatch(f.name):
            if now - st.st_mtime > stale_after:
                try:
                    f.unlink()
                except OSError:
                    pass
        elif _ours(f):
            files.append((st.st_mtime, st.st_size, f))
    total = sum(size for _, size, _ in files)
    for _, size, f in sorted(files):  # oldest use first
        if total <= budget:
            break
        if f == keep:
            continue
        try:
            f.unlink()
            total -= size
        except OSError:
            pass


FORMAT = "o3dheat-spectrum-1"
_SPARSE = ("stiffness", "mass")
_DENSE = ("eigenvalues", "eigenvectors", "areas", "residuals")


def spectrum_arrays(s):
    """The members of a :meth:`o3dheat.Spectrum.save <o3dheat.spectral.spectrum.Spectrum.save>` file (plain arrays, no pickles)."""
    out = {"format": np.array(FORMAT), "mass_kind": np.array(s.mass_kind), "backend": np.array(s.backend),
           "sigma": np.array(float(s.sigma))}
    out.update({name: np.asarray(getattr(s, name), dtype=np.float64) for name in _DENSE})
    for name in _SPARSE:
        A = getattr(s, name).tocsc()
        out.update({f"{name}_data": A.data, f"{name}_indices": A.indices, f"{name}_indptr": A.indptr,
                    f"{name}_shape": np.array(A.shape, dtype=np.int64)})
    if s.faces is not None:
        out["faces"] = np.asarray(s.faces, dtype=np.int64)
    if s.inverse_mass_bound is not None:
        out["inverse_mass_bound"] = np.asarray(s.inverse_mass_bound, dtype=np.float64)
    return out


def read_spectrum(path):
    """The fields of a :class:`o3dheat.Spectrum <o3dheat.spectral.spectrum.Spectrum>` from a :meth:`~o3dheat.spectral.spectrum.Spectrum.save` file,
    unchecked (the caller checks them); a MeshError when the file is not one, a
    :class:`~o3dheat.errors.NoSuchFile` when it is missing, the file system's OSError when it cannot
    be read (a folder, no permission)."""
    path = Path(path)
    data = read_regular(path, "spectrum file")  # a FIFO or a device is refused, not waited on
    try:
        with np.load(io.BytesIO(data), allow_pickle=False) as z:
            a = {name: z[name] for name in z.files}
    except OSError:
        raise  # a file-system failure stays an OSError
    except Exception as e:
        raise MeshError(f"{path} is not a readable .npz file ({e})") from None
    if "format" not in a or str(a["format"]) != FORMAT:
        raise MeshError(f"{path} is not a spectrum saved by o3dheat (Spectrum.save / o3dheat spectrum -o): "
                        f"it has {', '.join(sorted(a)) or 'no arrays'}")
    try:
        fields = {name: np.asarray(a[name], dtype=np.float64) for name in _DENSE}
        for name in _SPARSE:
            A = sp.csc_matrix((a[f"{name}_data"], a[f"{name}_indices"], a[f"{name}_indptr"]),
                              shape=tuple(int(x) for x in a[f"{name}_shape"]))
            A.check_format(full_check=True)  # indices in range: products with A read only its own memory
            fields[name] = A
        faces = a.get("faces")
        if faces is not None and not np.issubdtype(faces.dtype, np.integer):
            raise MeshError(f"{path}: faces must be integer vertex indices, got dtype {faces.dtype} (a float "
                            "index would be truncated to another vertex)")
        fields.update(mass_kind=str(a["mass_kind"]), backend=str(a["backend"]), sigma=float(a["sigma"]),
                      faces=faces, inverse_mass_bound=a.get("inverse_mass_bound"))
    except (KeyError, ValueError, TypeError, IndexError) as e:
        raise MeshError(f"{path}: a broken spectrum file ({type(e).__name__}: {e})") from None
    if fields["eigenvectors"].ndim != 2 or fields["eigenvalues"].ndim != 1 or fields["eigenvalues"].size == 0:
        raise MeshError(f"{path}: eigenvectors must be a matrix and eigenvalues a non-empty vector")
    return fields


def check_loaded(s, path):
    """The checks of :meth:`o3dheat.Spectrum.load <o3dheat.spectral.spectrum.Spectrum.load>` (a MeshError naming the first that fails)."""
    lam, X, L, B = s.eigenvalues, s.eigenvectors, s.stiffness, s.mass
    n, k = X.shape
    shapes = {"stiffness": L.shape, "mass": B.shape}
    for name, shape in shapes.items():
        if shape != (n, n):
            raise MeshError(f"{path}: {name} is {shape[0]} x {shape[1]}, the eigenvectors have {n} rows")
    for name, a in (("eigenvalues", lam), ("residuals", s.residuals), ("areas", s.areas)):
        if a.shape != ((k,) if name != "areas" else (n,)):
            raise MeshError(f"{path}: {name} has shape {a.shape}")
    bound = s.inverse_mass_bound
    if bound is not None and np.shape(bound) != (n,):
        raise MeshError(f"{path}: inverse_mass_bound has shape {np.shape(bound)}, not ({n},)")
    if not all(np.all(np.isfinite(a)) for a in (lam, X, L.data, B.data, s.residuals, s.areas)
               + (() if bound is None else (bound,))):
        raise MeshError(f"{path}: non-finite values")
    if np.any(s.areas < 0) or (bound is not None and np.any(bound < 0)):
        raise MeshError(f"{path}: negative areas or inverse-mass bound")
    if s.mass_kind != "given":
        try:
            fem.check_mass_kind(s.mass_kind)
        except MeshError as e:
            raise MeshError(f"{path}: {e}") from None
    if np.any(np.diff(lam) < 0) or lam[0] < 0:
        raise MeshError(f"{path}: the eigenvalues are not ascending and >= 0")
    if s.faces is not None and (s.faces.ndim != 2 or s.faces.shape[1] != 3 or s.faces.size
                                and (s.faces.min() < 0 or s.faces.max() >= n)):
        raise MeshError(f"{path}: faces of shape {s.faces.shape} do not index the {n} vertices")
    res = residuals(L, B, lam, X)
    if res.max() > 1e-2 or np.any(res > np.maximum(10 * s.residuals, 1e-12)):
        raise MeshError(f"{path}: the eigenpairs do not solve L x = λ B x for the stored operators "
                        f"(residual {res.max():.1e}, stored {s.residuals.max():.1e})")
    G = X.T @ (B @ X)
    G[np.diag_indices(k)] -= 1.0
    if np.abs(G).max() > 1e-6:
        raise MeshError(f"{path}: the eigenvectors are not B-orthonormal (|XᵀBX - I| = {np.abs(G).max():.1e})")
