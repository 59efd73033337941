"""o3dheat.topology.critical: PL critical points (PAPER.md row P12) and the compiled loops' loading."""

import logging

import numpy as np
import open3d as o3d
import pytest
from conftest import grid, icosphere, torus
from topology_cases import SURFACES, bipyramid, brute_critical, fields, reference_edges, upright_torus_height

import o3dheat
from o3dheat.topology import Surface


def test_upright_torus_height_function():
    mesh, h = upright_torus_height()
    cp = o3dheat.critical_points(mesh, h)
    assert cp.counts == (1, 2, 1)
    V = mesh[0]
    assert V[cp.minima[0], 0] == V[:, 0].min() and V[cp.maxima[0], 0] == V[:, 0].max()
    assert np.allclose(np.abs(V[cp.saddles, 0]), 0.6, atol=0.02)  # the inner equator R - r


@pytest.mark.parametrize("name", list(SURFACES))
def test_morse_count_equals_euler_characteristic(name, caplog):
    (V, F), chi = SURFACES[name]
    assert Surface((V, F)).euler_characteristic == chi
    for _, f in fields(len(V), 1):
        with caplog.at_level(logging.WARNING, logger="o3dheat"):
            cp = o3dheat.critical_points((V, F), f)
        assert cp.euler_characteristic == chi


@pytest.mark.parametrize("name", ["sphere", "torus", "disk", "annulus", "irregular"])
def test_critical_points_match_brute_force(name):
    (V, F), _ = SURFACES[name]
    for label, f in fields(len(V), 2):
        cp = o3dheat.critical_points((V, F), f)
        ref = brute_critical(F, f)
        assert cp.minima.tolist() == sorted(ref["min"]), label
        assert cp.maxima.tolist() == sorted(ref["max"]), label
        assert dict(zip(cp.saddles.tolist(), cp.saddle_multiplicity.tolist(), strict=True)) == ref["saddle"], label


def test_monkey_saddle_has_multiplicity_two():
    # a vertex whose cyclic link alternates low/high three times: Re((x + iy)^3)
    k = 12
    ang = 2 * np.pi * np.arange(k) / k
    V = np.concatenate([[[0, 0, 0]], np.stack([np.cos(ang), np.sin(ang), np.zeros(k)], 1)])
    F = np.array([[0, 1 + i, 1 + (i + 1) % k] for i in range(k)])
    f = np.concatenate([[0.0], np.cos(3 * ang)])
    cp = o3dheat.critical_points((V, F), f)
    assert cp.saddles.tolist() == [0] and cp.saddle_multiplicity.tolist() == [2]
    assert cp.euler_characteristic == 1  # a disk


def test_boundary_rule():
    V, F = grid(2.0, 1.0, 12, 8)  # a disk, χ = 1
    cp = o3dheat.critical_points((V, F), V[:, 0] + 0.1 * V[:, 1])  # a tilted plane
    # the minimum is the lowest boundary corner; the highest corner is regular (boundary maximum)
    assert cp.counts == (1, 0, 0)
    assert cp.minima.tolist() == [int(np.argmin(V[:, 0] + 0.1 * V[:, 1]))]
    # a boundary vertex with two lower runs along its path is a saddle: a valley on each side
    cp = o3dheat.critical_points((V, F), -np.abs(V[:, 0] - 1.0) + 0.01 * V[:, 1])
    assert cp.counts[1] >= 1 and cp.euler_characteristic == 1


def test_constant_field_is_documented_behaviour(caplog):
    V, F = torus(1.0, 0.4, 24, 12)
    with caplog.at_level(logging.WARNING, logger="o3dheat"):
        cp = o3dheat.critical_points((V, F), np.ones(len(V)))
    assert "constant" in caplog.text and cp.euler_characteristic == 0
    d = o3dheat.persistence((V, F), np.ones(len(V)))
    assert np.all(d.persistence == 0)


def test_high_degree_vertex_is_classified():
    V, F = bipyramid(200)
    f = V[:, 0] + 0.01 * V[:, 2] + 0.001 * np.arange(len(V))
    cp = o3dheat.critical_points((V, F), f)
    ref = brute_critical(F, f)
    assert cp.minima.tolist() == sorted(ref["min"]) and cp.maxima.tolist() == sorted(ref["max"])
    assert dict(zip(cp.saddles.tolist(), cp.saddle_multiplicity.tolist(), strict=True)) == ref["saddle"]
    # the apexes see the whole cycle: sin(3θ) alternates six times, a saddle of multiplicity 2
    g = np.concatenate([[0.0, 0.0], np.sin(3 * 2 * np.pi * np.arange(200) / 200)])
    cp = o3dheat.critical_points((V, F), g)
    assert cp.saddles[:2].tolist() == [0, 1] and cp.saddle_multiplicity[:2].tolist() == [2, 2]
    S = Surface((V, F))
    np.testing.assert_array_equal(S.E, reference_edges(S.F, S.n)[0])
    assert S.degree[:2].tolist() == [200, 200]


def test_compiled_loops_are_cached():
    """The numba cache of the compiled loops is written (beside the module, or NUMBA_CACHE_DIR),
    so that only the first call of an installation compiles."""
    from pathlib import Path

    from o3dheat.topology._loops import LOOPS, kernel

    V, F = icosphere(1)
    o3dheat.persistence((V, F), V[:, 0])
    for name in LOOPS:
        k = kernel(name)
        assert k.signatures, name
        assert Path(k._cache._cache_file._index_path).is_file(), name


def test_compiled_in_this_process_says_whether_the_loops_were_compiled_or_loaded(tmp_path):
    import os
    import subprocess
    import sys

    code = ("import open3d as o3d, o3dheat, o3dheat.topology as T;"
            "m = o3d.t.geometry.TriangleMesh.create_sphere(1.0, 8);"
            "o3dheat.critical_points(m, m.vertex.positions.numpy()[:, 2]);"
            "print(T.compiled_in_this_process())")
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path))
    # a cache folder of its own: numba uses it only when the module's own folder is not writable,
    # so compare a first run with a second one (the second loads what the first wrote or found)
    first = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=300)
    second = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=300)
    assert first.returncode == 0 and second.returncode == 0, first.stderr[-500:] + second.stderr[-500:]
    assert first.stdout.strip() in ("True", "False")
    assert second.stdout.strip() == "False"  # cached by then


def test_compiled_in_this_process_counts_cache_misses(monkeypatch):
    import types

    import o3dheat._jit as J
    import o3dheat.topology.critical as T

    def fake(misses):
        return types.SimpleNamespace(stats=types.SimpleNamespace(cache_misses={("sig",): misses}))

    mod = "o3dheat.topology._loops"
    monkeypatch.setattr(J, "_COMPILED", {(mod, "a"): fake(0), (mod, "b"): fake(0), ("other", "c"): fake(1)})
    assert T.compiled_in_this_process() is False  # another module's compilation is not this one's
    monkeypatch.setattr(J, "_COMPILED", {(mod, "a"): fake(0), (mod, "b"): fake(1)})
    assert T.compiled_in_this_process() is True


def test_warm_up_loads_every_compiled_loop():
    """topology.warm_up() (run by each Dask worker at start) leaves no loop to load in a task."""
    import subprocess
    import sys

    code = ("import o3dheat.topology.critical as T, o3dheat._jit as J; T.warm_up(); "
            "print(sorted(name for mod, name in J._COMPILED if mod == 'o3dheat.topology._loops'))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip().splitlines()[-1] == str(sorted(["arcs", "checked_copy", "classify", "duplicates",
                                                       "links", "pack_keys", "settle_runs", "sweeps"]))
    from o3dheat.topology import _loops

    assert sorted(_loops.LOOPS) == sorted(["arcs", "checked_copy", "classify", "duplicates", "links", "pack_keys",
                                           "settle_runs", "sweeps"])


def test_critical_points_have_a_length_the_number_of_critical_vertices():
    """Issue 22: CriticalPoints had no len(). len counts vertices; counts weigh saddles by
    multiplicity (a monkey saddle: one vertex, multiplicity 2)."""

    m = o3d.t.geometry.TriangleMesh.create_torus()
    cp = o3dheat.critical_points(m, m.vertex.positions.numpy()[:, 0])
    assert len(cp) == 4 == sum(cp.counts) and len(cp) == int((cp.kind > 0).sum())
    # a monkey saddle: Re (x + iy)^3 at the centre of a fan of 6 triangles
    ang = np.arange(6) * np.pi / 3
    V = np.vstack([[0, 0, 0], np.c_[np.cos(ang), np.sin(ang), np.zeros(6)]])
    F = np.array([[0, 1 + i, 1 + (i + 1) % 6] for i in range(6)])
    f = np.real((V[:, 0] + 1j * V[:, 1]) ** 3)
    mk = o3dheat.critical_points((V, F), f)
    assert list(mk.saddles) == [0] and mk.saddle_multiplicity.tolist() == [2]
    assert len(mk) == len(mk.minima) + 1 + len(mk.maxima) == sum(mk.counts) - 1
