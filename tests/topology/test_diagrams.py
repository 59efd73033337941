"""o3dheat.topology.diagrams: persistence pairs and simplification (PAPER.md rows P15, P16)."""

import numpy as np
import pytest
from conftest import icosphere, irregular
from topology_cases import (
    ESSENTIAL,
    RANDOM_MESHES,
    SURFACES,
    brute_persistence,
    field_strategy,
    fields,
    finite,
    gudhi_diagrams,
    reference_critical,
    reference_persistence,
)

import o3dheat
from o3dheat.topology import Surface


@pytest.mark.parametrize("name", list(SURFACES))
def test_persistence_accounts_for_every_critical_point(name):
    (V, F), _ = SURFACES[name]
    for label, f in fields(len(V), 3):
        cp = o3dheat.critical_points((V, F), f)
        d = o3dheat.persistence((V, F), f)
        want = np.zeros(len(V), int)
        want[cp.minima] += 1
        want[cp.maxima] += 1
        np.add.at(want, cp.saddles, cp.saddle_multiplicity)
        got = np.bincount(np.concatenate([d.pairs.reshape(-1), d.essential]), minlength=len(V))
        assert np.array_equal(got, want), label
        kinds = cp.kind
        assert np.all(kinds[d.pairs[d.dimension == 0, 0]] == 1)  # minimum - saddle
        assert np.all(kinds[d.pairs[d.dimension == 1, 0]] == 3)  # maximum - saddle
        assert np.all(kinds[d.pairs[:, 1]] == 2)
        assert tuple(np.bincount(d.essential_dimension, minlength=3)) == ESSENTIAL[name], label
        assert np.all(d.persistence >= 0) and np.allclose(d.persistence, np.abs(d.death - d.birth))


@pytest.mark.parametrize("name", ["sphere", "torus", "annulus", "disk"])
def test_persistence_matches_matrix_reduction(name):
    (V, F), _ = SURFACES[name]
    rng = np.random.default_rng(4)
    f = rng.standard_normal(len(V))
    d = o3dheat.persistence((V, F), f)
    ours = sorted((0, int(a), int(b)) for a, b in d.pairs[d.dimension == 0])
    ours += sorted((1, int(b), int(a)) for a, b in d.pairs[d.dimension == 1])  # (saddle, max)
    assert sorted(ours) == sorted(brute_persistence(F, f))


@pytest.mark.parametrize("name", list(SURFACES))
def test_persistence_matches_gudhi(name):
    (V, F), _ = SURFACES[name]
    for label, f in fields(len(V), 5):
        g = gudhi_diagrams(F, f)
        d = o3dheat.persistence((V, F), f)
        D0 = finite(d.intervals(0))
        D1 = finite(d.intervals(1)[:, ::-1])  # read as sublevel (saddle, maximum)
        assert np.array_equal(D0, finite(g[0])), label
        assert np.array_equal(D1, finite(g[1])), label
        # essential classes: components, 1-cycles, closed components
        inf = [int(np.sum(~np.isfinite(x[:, 1]))) if len(x) else 0 for x in g]
        assert tuple(inf) == ESSENTIAL[name], label


def test_persistence_is_stable():
    gudhi = pytest.importorskip("gudhi")
    V, F = irregular()
    rng = np.random.default_rng(6)
    f = V[:, 0] + 0.2 * rng.standard_normal(len(V))
    for eps in (1e-3, 1e-2, 0.1):
        e = eps * rng.uniform(-1, 1, len(V))
        d1, d2 = o3dheat.persistence((V, F), f), o3dheat.persistence((V, F), f + e)
        for k in (0, 1):
            assert gudhi.bottleneck_distance(d1.intervals(k), d2.intervals(k)) <= np.abs(e).max() + 1e-12


def test_simplification_is_monotone_and_keeps_essentials():
    V, F = irregular()
    f = V[:, 2] + 0.05 * np.random.default_rng(7).standard_normal(len(V))
    d = o3dheat.persistence((V, F), f)
    cp = o3dheat.critical_points((V, F), f)
    all_critical = np.unique(np.concatenate([cp.minima, cp.saddles, cp.maxima]))
    assert np.array_equal(o3dheat.simplify_critical_points((V, F), f), all_critical)
    prev = None
    for delta in np.linspace(0, d.persistence.max() * 1.01, 12):
        keep = o3dheat.simplify_critical_points((V, F), f, delta=delta, diagram=d)
        assert set(d.essential) <= set(keep)
        if prev is not None:
            assert set(keep) <= set(prev)
        prev = keep
    assert set(prev) == set(d.essential)
    sizes = [len(o3dheat.simplify_critical_points((V, F), f, keep_fraction=q, diagram=d))
             for q in (0.0, 0.1, 0.5, 1.0)]
    assert sizes == sorted(sizes) and sizes[-1] == len(all_critical)


@pytest.mark.parametrize("kwargs", [dict(delta=-1.0), dict(delta=np.nan), dict(keep_fraction=1.5),
                                    dict(delta=0.1, keep_fraction=0.5), dict(diagram="no")])
def test_simplification_bad_arguments(kwargs):
    V, F = icosphere(1)
    with pytest.raises(o3dheat.MeshError):
        o3dheat.simplify_critical_points((V, F), V[:, 0], **kwargs)


def test_hypothesis_same_as_previous_implementation_and_gudhi():
    """Critical points and persistence equal the previous implementation's, pair for pair, and the
    finite diagrams equal gudhi's, on random fields with ties and plateaus, on surfaces with
    boundaries, several components, non-orientable ones and high-degree vertices."""
    from hypothesis import HealthCheck, given, settings

    @settings(max_examples=80, deadline=None, suppress_health_check=[HealthCheck.too_slow])
    @given(field_strategy())
    def check(case):
        name, _, f = case
        V, F = RANDOM_MESHES[name]
        S = Surface((V, F))
        cp = o3dheat.critical_points(S, f)
        mins, sads, mult, maxs = reference_critical(S, f)
        assert np.array_equal(cp.minima, mins) and np.array_equal(cp.maxima, maxs)
        assert np.array_equal(cp.saddles, sads) and np.array_equal(cp.saddle_multiplicity, mult)
        assert cp.euler_characteristic == S.euler_characteristic
        d = o3dheat.persistence(S, f)
        pairs, dim, ess, edim = reference_persistence(S, f)
        np.testing.assert_array_equal(d.pairs, pairs)
        np.testing.assert_array_equal(d.dimension, dim)
        np.testing.assert_array_equal(d.essential, ess)
        np.testing.assert_array_equal(d.essential_dimension, edim)
        np.testing.assert_array_equal(d.birth, f[pairs[:, 0]])
        np.testing.assert_array_equal(d.death, f[pairs[:, 1]])
        g = gudhi_diagrams(F, f)
        assert np.array_equal(finite(d.intervals(0)), finite(g[0]))
        assert np.array_equal(finite(d.intervals(1)[:, ::-1]), finite(g[1]))

    check()


def test_generic_fields_follow_a_renumbering():
    """Without ties, the diagram does not depend on the vertex numbering."""
    rng = np.random.default_rng(11)
    for name in ("torus", "annulus", "several"):
        V, F = RANDOM_MESHES[name]
        f = rng.standard_normal(len(V))
        perm = rng.permutation(len(V))  # new vertex i is old vertex perm[i]
        inv = np.argsort(perm)
        d, dp = o3dheat.persistence((V, F), f), o3dheat.persistence((V[perm], inv[F]), f[perm])
        assert sorted(map(tuple, d.pairs.tolist())) == sorted(map(tuple, perm[dp.pairs].tolist()))
        assert sorted(d.essential.tolist()) == sorted(perm[dp.essential].tolist())


def _shuffled(V, F, seed):
    """The same surface with its vertices renumbered, its faces reordered and about half of them
    turned over (orientations no longer consistent: the adjacency's general path)."""
    rng = np.random.default_rng(seed)
    perm = rng.permutation(len(V))  # new vertex i is old vertex perm[i]
    inv = np.argsort(perm)
    F = inv[F][rng.permutation(len(F))]
    flip = rng.random(len(F)) < 0.5
    F[flip] = F[flip][:, ::-1]
    return V[perm], F, perm


@pytest.mark.parametrize("name", list(RANDOM_MESHES))
def test_persistence_equals_previous_implementation_on_renumbered_and_flipped_meshes(name):
    """Issue 31 (the adjacency in link order, the runs of lower neighbours, the packed sorts): pair
    for pair the previous implementation's diagram (topology_cases.reference_persistence) and
    gudhi's, with the faces in any order and orientation."""
    V0, F0 = RANDOM_MESHES[name]
    for seed in range(3):
        V, F, _ = _shuffled(V0, F0, seed) if seed else (V0, F0, None)
        S = Surface((V, F))
        for label, f in fields(len(V), seed):
            d = o3dheat.persistence(S, f)
            pairs, dim, ess, edim = reference_persistence(S, f)
            np.testing.assert_array_equal(d.pairs, pairs, err_msg=label)
            np.testing.assert_array_equal(d.dimension, dim)
            np.testing.assert_array_equal(d.essential, ess)
            np.testing.assert_array_equal(d.essential_dimension, edim)
            g = gudhi_diagrams(F, f)
            assert np.array_equal(finite(d.intervals(0)), finite(g[0])), label
            assert np.array_equal(finite(d.intervals(1)[:, ::-1]), finite(g[1])), label


def test_persistence_of_noisy_fields_on_a_larger_sphere_equals_gudhi_and_the_previous_implementation():
    """Many critical points (most vertices), ties, and the same surface turned over in parts."""
    gudhi = pytest.importorskip("gudhi")
    V0, F0 = icosphere(4)
    rng = np.random.default_rng(12)
    for seed, (V, F) in enumerate([(V0, F0), _shuffled(V0, F0, 5)[:2]]):
        for f in (V[:, 2] + 0.3 * rng.standard_normal(len(V)), np.round(rng.standard_normal(len(V)), 1)):
            d = o3dheat.persistence((V, F), f)
            pairs, dim, ess, edim = reference_persistence(Surface((V, F)), f)
            np.testing.assert_array_equal(d.pairs, pairs, err_msg=str(seed))
            np.testing.assert_array_equal(d.essential, ess)
            np.testing.assert_array_equal(d.essential_dimension, edim)
            g = gudhi_diagrams(F, f)
            for k in (0, 1):  # the same finite pairs (bottleneck distance 0, up to gudhi's rounding)
                ours = finite(d.intervals(k) if k == 0 else d.intervals(1)[:, ::-1])
                assert np.array_equal(ours, finite(g[k]))
                assert gudhi.bottleneck_distance(ours, finite(g[k])) < 1e-300
            inf = tuple(int(np.sum(~np.isfinite(x[:, 1]))) if len(x) else 0 for x in g)
            assert inf == tuple(np.bincount(d.essential_dimension, minlength=3))


def test_packed_order_is_lexicographic():
    """The order of persistence (leading bits and index in one word, numpy's vectorised sort,
    near-ties settled) is np.lexsort((second, key)), -0.0 equal to 0.0, for keys with ties,
    near-ties and extremes."""
    from o3dheat.topology.diagrams import _order

    rng = np.random.default_rng(3)
    for trial in range(60):
        N = int(rng.integers(1, 2000))
        key = [rng.standard_normal(N), np.round(rng.standard_normal(N), 1), 1 + rng.integers(0, 5, N) * 1e-15,
               np.where(rng.random(N) < 0.5, 0.0, -0.0), 1 + 1e-12 * rng.standard_normal(N),
               rng.integers(-3, 3, N) * rng.choice([1.0, 1e-300, 1e300, 5e307], N)][trial % 6]
        second = rng.permutation(3 * N)[:N] if trial % 2 else np.arange(N)
        np.testing.assert_array_equal(_order(key, second), np.lexsort((second, key)), err_msg=str(trial))
