"""o3dheat.spectral.cache: the in-memory cache of spectra, the signed disk entries of eigensolve."""

import logging

import numpy as np
import pytest
from conftest import icosphere, torus

import o3dheat


def test_cache(tmp_path, irregular_mesh):
    a = o3dheat.eigensolve(irregular_mesh, k=10, cache=tmp_path, method="arpack")
    assert a.timings["cache"] is False and len(list(tmp_path.glob("spectrum-*.npz"))) == 1
    b = o3dheat.eigensolve(irregular_mesh, k=10, cache=tmp_path, method="arpack")
    assert b.timings["cache"] is True
    np.testing.assert_array_equal(a.eigenvectors, b.eigenvectors)
    c = o3dheat.eigensolve(irregular_mesh, k=11, cache=tmp_path, method="arpack")
    assert c.timings["cache"] is False  # another k is another entry
    # a corrupt cache file is ignored (and replaced), never fatal
    for p in tmp_path.glob("spectrum-*.npz"):
        p.write_bytes(b"garbage")
    d = o3dheat.eigensolve(irregular_mesh, k=10, cache=tmp_path, method="arpack")
    np.testing.assert_array_equal(a.eigenvalues, d.eigenvalues)


def test_cache_key_has_the_tolerance_and_tampered_files_are_recomputed(tmp_path, irregular_mesh, caplog):
    o3dheat.eigensolve(irregular_mesh, k=10, cache=tmp_path, method="lanczos", tol=1e-2)  # the loose one
    tight = o3dheat.eigensolve(irregular_mesh, k=10, cache=tmp_path, method="lanczos", tol=1e-10)
    assert tight.timings["cache"] is False and len(list(tmp_path.glob("spectrum-*.npz"))) == 2
    assert o3dheat.eigensolve(irregular_mesh, k=10, cache=tmp_path, method="lanczos", tol=1e-2).timings["cache"]
    # a file whose arrays load but do not solve the problem is never returned
    for p in tmp_path.glob("spectrum-*.npz"):
        with np.load(p) as z:
            data = dict(z)
        data["eigenvalues"] = data["eigenvalues"] * 1.01
        np.savez(p, **data)
    with caplog.at_level(logging.WARNING, logger="o3dheat"):
        again = o3dheat.eigensolve(irregular_mesh, k=10, cache=tmp_path, method="lanczos", tol=1e-10)
    assert again.timings["cache"] is False and "tampered or corrupt" in caplog.text
    np.testing.assert_allclose(again.eigenvalues, tight.eigenvalues, rtol=1e-12)


def test_default_cache_dir(monkeypatch, tmp_path, irregular_mesh):
    monkeypatch.setenv("O3DHEAT_CACHE", str(tmp_path / "c"))
    a = o3dheat.eigensolve(irregular_mesh, k=6, cache=True)
    assert len(list((tmp_path / "c").glob("spectrum-*.npz"))) == 1
    assert o3dheat.eigensolve(irregular_mesh, k=6, cache=True).timings["cache"] is True
    assert a.timings["cache"] is False


def test_unwritable_cache_is_not_fatal(tmp_path, irregular_mesh, caplog):
    blocker = tmp_path / "file"
    blocker.write_text("not a folder")
    with caplog.at_level(logging.WARNING, logger="o3dheat"):
        s = o3dheat.eigensolve(irregular_mesh, k=4, cache=blocker / "sub")
    assert s.k == 4 and "could not write the spectrum cache" in caplog.text


def test_one_cache_bounded_cleaned_and_in_the_platform_folder(tmp_path, monkeypatch, irregular_mesh):
    import os
    import time

    import o3dheat.spectral.cache as C
    import o3dheat.spectral.spectrum as S

    monkeypatch.delenv("O3DHEAT_CACHE", raising=False)
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    if not (os.name == "nt" or __import__("sys").platform == "darwin"):
        assert C.default_cache_dir() == tmp_path / "xdg" / "o3dheat"
    folder = tmp_path / "c"
    folder.mkdir()
    stale = folder / "spectrum-abc.npz.tmp"  # left by a killed writer
    stale.write_bytes(b"x")
    os.utime(stale, (time.time() - 7200,) * 2)
    fresh = folder / "spectrum-def.npz.tmp"  # a writer at work
    fresh.write_bytes(b"x")
    monkeypatch.setenv("O3DHEAT_CACHE_MAX_MB", "0.02")  # less than one spectrum
    V, F = irregular_mesh
    for k in (5, 6, 7):
        o3dheat.eigensolve((V, F), k=k, cache=folder)
        time.sleep(0.01)
    kept = sorted(folder.glob("spectrum-*.npz"))
    assert not stale.exists() and fresh.exists()
    assert len(kept) == 1  # over the budget: only the newest stays
    assert o3dheat.eigensolve((V, F), k=7, cache=folder).timings["cache"] is True  # the newest is kept
    # the filters, the robust point-cloud operators and user code share the one memory cache
    C.clear_cache()
    a = S.shared_eigensolve(V, F, k=6)
    assert o3dheat.pipelines.filters.shared_spectrum(V, F, k=6) is a and len(C.SPECTRA.entries) == 1


def test_the_memory_cache_is_bounded_in_bytes_and_keeps_the_newest(monkeypatch):
    import o3dheat.spectral.cache as C
    import o3dheat.spectral.spectrum as S

    C.clear_cache()
    meshes = [icosphere(2), icosphere(3), torus()]
    sizes = []
    for V, F in meshes:
        S.shared_eigensolve(V, F, k=6)
        sizes.append(list(C.SPECTRA.entries.values())[-1][1])
    assert len(C.SPECTRA.entries) == 3 and min(sizes) > 0
    monkeypatch.setenv("O3DHEAT_MEMORY_CACHE_MB", str((sizes[1] + sizes[2]) / 2**20))
    V, F = icosphere(1)
    S.shared_eigensolve(V, F, k=6)  # over budget: the least recently used go first
    assert len(C.SPECTRA.entries) == 2
    monkeypatch.setenv("O3DHEAT_MEMORY_CACHE_MB", "0")
    newest = S.shared_eigensolve(*meshes[0], k=6)
    assert len(C.SPECTRA.entries) == 1 and S.shared_eigensolve(*meshes[0], k=6) is newest  # the newest stays
    monkeypatch.setenv("O3DHEAT_MEMORY_CACHE_MB", "lots")
    with pytest.raises(o3dheat.MeshError, match="O3DHEAT_MEMORY_CACHE_MB"):
        S.shared_eigensolve(*meshes[1], k=6)
    C.clear_cache()
    assert len(C.SPECTRA.entries) == 0


def test_the_cache_reads_only_its_own_writes(tmp_path, irregular_mesh, caplog, monkeypatch):
    """Issue 22: crafted entries (k copies of one eigenvector; eigenpairs 5..14 stored as the
    smallest 10) passed the residual check. Entries are now signed with the folder's secret key:
    a file not written by o3dheat for this key is recomputed, and the pruning never deletes a
    user's own file."""
    import os
    import shutil

    import o3dheat.spectral.cache as C

    V, F = irregular_mesh
    ref = o3dheat.eigensolve((V, F), k=10, cache=tmp_path, method="arpack")
    more = o3dheat.eigensolve((V, F), k=14, cache=False, method="arpack")
    key_file = tmp_path / ".o3dheat-key"
    assert key_file.stat().st_size == 32 and (os.name == "nt" or key_file.stat().st_mode & 0o077 == 0)
    (entry,) = tmp_path.glob("spectrum-*.npz")
    with np.load(entry) as z:
        genuine = dict(z)
    x0 = more.eigenvectors[:, :1]
    crafted = {"copies": {**genuine, "eigenvalues": np.zeros(10), "eigenvectors": np.repeat(x0, 10, axis=1),
                          "residuals": np.zeros(10)},
               "shifted": {**genuine, "eigenvalues": more.eigenvalues[4:14], "eigenvectors": more.eigenvectors[:, 4:14],
                           "residuals": more.residuals[4:14]}}
    for name, data in crafted.items():
        np.savez(entry, **data)  # the genuine signature kept: it does not match the new arrays
        with caplog.at_level(logging.WARNING, logger="o3dheat"):
            caplog.clear()
            s = o3dheat.eigensolve((V, F), k=10, cache=tmp_path, method="arpack")
        assert s.timings["cache"] is False and "signature does not match" in caplog.text, name
        np.testing.assert_allclose(s.eigenvalues, ref.eigenvalues, rtol=1e-10)
    # an entry copied from another cache folder (another key) is not trusted either
    other = tmp_path / "other"
    o3dheat.eigensolve((V, F), k=10, cache=other, method="arpack")
    shutil.copy(next(other.glob("spectrum-*.npz")), entry)
    assert o3dheat.eigensolve((V, F), k=10, cache=tmp_path, method="arpack").timings["cache"] is False
    assert o3dheat.eigensolve((V, F), k=10, cache=tmp_path, method="arpack").timings["cache"] is True
    # pruning: a user's own spectrum-*.npz files stay, whatever the budget
    mine = [tmp_path / "spectrum-mine.npz", tmp_path / ("spectrum-" + "0" * 31 + "x.npz")]
    for p in mine:
        np.savez(p, eigenvalues=ref.eigenvalues)
    monkeypatch.setenv("O3DHEAT_CACHE_MAX_MB", "0")
    o3dheat.eigensolve((V, F), k=6, cache=tmp_path, method="arpack")
    assert all(p.exists() for p in mine) and len(list(tmp_path.glob("spectrum-*.npz"))) == 3
    for bad in ("-1", "nan", "lots"):
        monkeypatch.setenv("O3DHEAT_CACHE_MAX_MB", bad)
        with pytest.raises(o3dheat.MeshError, match="O3DHEAT_CACHE_MAX_MB must be a number of megabytes >= 0"):
            C.cache_max_bytes()


def test_a_cache_key_or_entry_that_is_not_a_private_regular_file_is_not_trusted_nor_waited_on(
        tmp_path, irregular_mesh, caplog):
    """Issue 30: a FIFO (or a link to /dev/zero) as the key or as an entry blocked eigensolve(cache=...)
    or read without bound; a key other users could write, or one in a folder they can write, was
    trusted, so a forged entry signed with it was served as a hit. Now ignored, with a warning, as ssh
    does with its keys."""
    import os
    import threading

    V, F = irregular_mesh
    key = tmp_path / ".o3dheat-key"

    def solve_in_time(folder):
        out = []
        worker = threading.Thread(target=lambda: out.append(o3dheat.eigensolve((V, F), k=6, cache=folder)),
                                  daemon=True)
        worker.start()
        worker.join(60)
        assert not worker.is_alive(), "eigensolve(cache=...) hangs"
        return out[0]

    os.mkfifo(key)
    with caplog.at_level("WARNING", logger="o3dheat"):
        assert solve_in_time(tmp_path).timings["cache"] is False
    assert "not a regular file" in caplog.text
    key.unlink()
    os.symlink("/dev/zero", key)
    caplog.clear()
    with caplog.at_level("WARNING", logger="o3dheat"):
        assert solve_in_time(tmp_path).timings["cache"] is False
    assert "no readable key" in caplog.text  # a link is not followed to the key
    key.unlink()
    solve_in_time(tmp_path)  # a key of its own now, and an entry
    (entry,) = tmp_path.glob("spectrum-*.npz")
    assert solve_in_time(tmp_path).timings["cache"] is True
    key.chmod(0o666)  # others may write the key: ignored
    caplog.clear()
    with caplog.at_level("WARNING", logger="o3dheat"):
        assert solve_in_time(tmp_path).timings["cache"] is False
    assert "readable or writable by others" in caplog.text
    key.chmod(0o600)
    tmp_path.chmod(0o777)  # a folder others may write in: not used
    caplog.clear()
    with caplog.at_level("WARNING", logger="o3dheat"):
        assert solve_in_time(tmp_path).timings["cache"] is False
    assert "other users may write in it" in caplog.text
    tmp_path.chmod(0o700)
    if os.geteuid() == 0:  # a key owned by another user: ignored
        os.chown(key, 12345, -1)
        caplog.clear()
        with caplog.at_level("WARNING", logger="o3dheat"):
            assert solve_in_time(tmp_path).timings["cache"] is False
        assert "owned by another user" in caplog.text
        os.chown(key, 0, -1)
    entry.unlink()
    os.mkfifo(entry)  # an entry that is a FIFO: recomputed, not waited on
    caplog.clear()
    with caplog.at_level("WARNING", logger="o3dheat"):
        assert solve_in_time(tmp_path).timings["cache"] is False
    assert "not a regular file" in caplog.text


def test_factors_count_their_own_bytes_and_room_is_made_before_a_new_one(monkeypatch):
    """Issue 35: a factor in the cache counted 0 bytes (its arrays live in CHOLMOD's memory), so
    every factor of a flow stayed, whatever the budget; and a new factor was made while the last
    one was still kept. A factor counts its nbytes now, and ``room`` drops results first."""
    import o3dheat.spectral.cache as C

    C.clear_cache()
    V, F = icosphere(4)
    flow = o3dheat.HeatFlow((V, F))
    flow.apply(V[:, 0], [1e-4, 1e-3, 1.0, 10.0])  # four decades: two shifts, two factors
    factors = [(k, b) for k, (v, b) in C.SPECTRA.entries.items() if k[0] == "heatflow-factor"]
    assert len(factors) == 2 and all(b >= v.nbytes > 0 for (k, b), v in
                                     zip(factors, [C.SPECTRA.entries[k][0] for k, _ in factors], strict=True))
    made = []

    class Sized:
        nbytes = 123

    monkeypatch.setenv("O3DHEAT_MEMORY_CACHE_MB", str(2 * factors[0][1] / 2**20))
    C.memoized(("other", 1), lambda: made.append(len(C.SPECTRA)) or Sized(), room=2 * factors[0][1])
    assert made == [0]  # everything dropped before computing: no room was left
    assert C.SPECTRA.entries[("other", 1)][1] == 123
    C.clear_cache()
