"""Feature-driven approximation and the scale hierarchy (PAPER.md rows P11, P14, P15, Fig. 1d)."""

import logging

import numpy as np
import pytest
from conftest import grid, icosphere, irregular

import o3dheat
from o3dheat.topology.approximation import project


@pytest.fixture(scope="module")
def kernel_irregular():
    V, F = irregular()
    return (V, F), o3dheat.HeatKernel(o3dheat.eigensolve((V, F), k=300, method="dense"))


@pytest.fixture(scope="module")
def kernel_regular():
    V, F = icosphere(4)
    return (V, F), o3dheat.HeatKernel(o3dheat.eigensolve((V, F), k=300))


def noisy(V, seed=0, amp=0.15):
    return V[:, 0] + np.sin(3 * V[:, 1]) + amp * np.random.default_rng(seed).standard_normal(len(V))


def test_projection():
    f = np.arange(5.0)
    assert project(f, [1, 3, 3]).tolist() == [0, 1, 0, 3, 0]
    assert project(f, np.array([True, False, False, False, True])).tolist() == [0, 0, 0, 0, 4]
    assert project(np.ones((5, 2)), []).sum() == 0
    for bad in ([5], [-1], [[0, 1]], np.ones(4, bool), [0.5]):
        with pytest.raises(o3dheat.MeshError):
            project(f, bad)


def test_feature_driven_identities(kernel_irregular):
    (V, F), K = kernel_irregular
    f = noisy(V)
    t = K.scales()[2]
    A = o3dheat.simplify_critical_points((V, F), f, keep_fraction=0.2)
    glob, loc = o3dheat.feature_driven(K, f, A, t)
    assert np.allclose(glob + loc, f)
    # linearity: Φ_t(pr_A f) + Φ_t(pr_{A^C} f) = Φ_t f
    Ac = np.setdiff1d(np.arange(len(V)), A)
    assert np.allclose(glob + o3dheat.feature_driven(K, f, Ac, t)[0], K.smooth(f, t))
    # the paper's definition: Σ_{i∈A} f_i Φ_t(e_i), without forming the basis in the library
    assert np.allclose(glob, K.canonic_basis(A, t) @ f[A])
    # A = everything: the plain feature map; A = ∅: nothing global
    assert np.allclose(o3dheat.feature_driven(K, f, np.ones(len(V), bool), t)[0], K.smooth(f, t))
    g0, l0 = o3dheat.feature_driven(K, f, [], t)
    assert np.all(g0 == 0) and np.allclose(l0, f)
    # batched over times and fields, like HeatKernel.smooth
    ts = K.scales()[:3]
    G, L = o3dheat.feature_driven(K, np.stack([f, 2 * f], 1), A, ts)
    assert G.shape == (len(V), 2, 3) and np.allclose(G[:, 1], 2 * G[:, 0])
    assert np.allclose(G[:, 0, 2], glob) and np.allclose(L[:, 0, :] + G[:, 0, :], f[:, None])


def test_feature_driven_bad_input(kernel_irregular):
    (V, F), K = kernel_irregular
    with pytest.raises(o3dheat.MeshError):
        o3dheat.feature_driven("K", V[:, 0], [0], 0.1)
    with pytest.raises(o3dheat.MeshError):
        o3dheat.feature_driven(K, V[:5, 0], [0], 0.1)
    with pytest.raises(o3dheat.MeshError):
        o3dheat.feature_driven(K, V[:, 0], [len(V)], 0.1)
    with pytest.raises(o3dheat.MeshError):
        o3dheat.feature_driven(K, V[:, 0], [0], -1.0)


def test_scale_space_fields_errors_and_variation(kernel_irregular):
    (V, F), K = kernel_irregular
    f = noisy(V)
    ss = o3dheat.scale_space(K, f)
    t = K.scales()
    assert np.array_equal(ss.scales, t)
    assert np.allclose(ss.fields, K.smooth(f, t))
    assert np.allclose(ss.errors, K.error(f, t))
    assert np.allclose(ss.variation, [np.abs(ss.fields[:, i + 1] - ss.fields[:, i]).max() for i in range(9)])
    assert ss.stop is None and ss.stop_index == 9 and not ss.stopped
    for i, c in enumerate(ss.critical):
        assert c.same_as(o3dheat.critical_points((V, F), ss.fields[:, i]))
        assert tuple(ss.critical_counts[i]) == c.counts and c.euler_characteristic == 2


def test_stop_criteria_stop_where_they_say(kernel_irregular):
    (V, F), K = kernel_irregular
    f = noisy(V)
    t = np.geomspace(K.scales()[0], 50 * K.scales()[-1], 12)
    ref = o3dheat.scale_space(K, f, scales=t)
    for tol in np.quantile(ref.variation, [0.1, 0.5, 0.9]):
        ss = o3dheat.scale_space(K, f, scales=t, stop="linf", tol=tol)
        j = ss.stop_index
        assert ss.stopped and ref.variation[j - 1] < tol and np.all(ref.variation[: j - 1] >= tol)
        assert np.array_equal(ss.field, ref.fields[:, j])
    never = o3dheat.scale_space(K, f, scales=t, stop="linf", tol=0.0)
    assert not never.stopped and never.stop_index == len(t) - 1
    ss = o3dheat.scale_space(K, f, scales=t, stop="critical_points")
    j = ss.stop_index
    same = [ref.critical[i].same_as(ref.critical[i - 1]) for i in range(1, len(t))]
    assert ss.stopped == any(same)
    if ss.stopped:
        assert same[j - 1] and not any(same[: j - 1])
    # the default tolerance is 1e-3 ‖f‖∞
    assert o3dheat.scale_space(K, f, scales=t, stop="linf").tol == pytest.approx(1e-3 * np.abs(f).max())


@pytest.mark.parametrize("which", ["kernel_regular", "kernel_irregular"])
def test_smoothing_lowers_the_number_of_critical_points(which, request):
    """The trend of Fig. 1(d): fewer critical points along the paper's scales."""
    (V, F), K = request.getfixturevalue(which)
    f = noisy(V, amp=0.3)
    raw = sum(o3dheat.critical_points((V, F), f).counts)
    ss = o3dheat.scale_space(K, f)
    total = ss.critical_counts.sum(axis=1)
    assert raw > total[0] >= total[-1]
    assert total[-1] < total[0]
    assert np.corrcoef(np.arange(len(total)), total)[0, 1] < -0.5
    assert np.all(ss.errors > 0)


@pytest.mark.parametrize("which", ["kernel_regular", "kernel_irregular"])
def test_log_grid_sweep_falls_to_a_handful(which, request):
    """Fig. 1(d) on the log grid: from what k eigenpairs resolve down to the height's extrema, the
    count falls overall; at the end Φ_t f is nearly its weighted mean (a handful of points)."""
    (V, F), K = request.getfixturevalue(which)
    f = noisy(V, amp=0.3)
    raw = sum(o3dheat.critical_points((V, F), f).counts)
    ss = o3dheat.scale_space(K, f, scales=K.scales(10, grid="log"))
    total = ss.critical_counts.sum(axis=1)
    assert raw > total[0] > total[-1]
    assert np.corrcoef(np.log(ss.scales), total)[0, 1] < -0.7
    assert total[-1] <= 6
    paper = o3dheat.scale_space(K, f).critical_counts.sum(axis=1)
    assert total[0] - total[-1] > paper[0] - paper[-1]  # it shows more than the paper's grid


def test_scale_space_bad_input(kernel_irregular):
    (V, F), K = kernel_irregular
    f = V[:, 0]
    for kwargs in (dict(stop="nope"), dict(scales=[0.2, 0.1]), dict(scales=[]), dict(tol=0.1),
                   dict(stop="linf", tol=-1.0), dict(scales=[-1.0, 1.0])):
        with pytest.raises(o3dheat.MeshError):
            o3dheat.scale_space(K, f, **kwargs)
    with pytest.raises(o3dheat.MeshError):
        o3dheat.scale_space(K, np.stack([f, f], 1))


def test_scale_space_on_a_non_manifold_mesh(caplog):
    V, F = grid(1.0, 1.0, 6, 6)
    a, b = F[0, 1], F[0, 2]  # an interior edge
    V2 = np.concatenate([V, [[0.5, 0.5, 1.0]]])
    F2 = np.concatenate([F, [[a, b, len(V)]]])  # a fin: a non-manifold edge
    K = o3dheat.HeatKernel(o3dheat.eigensolve((V2, F2), k=10))
    with caplog.at_level(logging.WARNING, logger="o3dheat"):
        ss = o3dheat.scale_space(K, V2[:, 0], stop="linf")
    assert np.all(ss.critical_counts == -1) and ss.critical is None and "non-manifold" in caplog.text
    with pytest.raises(o3dheat.MeshError, match="2-manifold"):
        o3dheat.scale_space(K, V2[:, 0], stop="critical_points")


def test_spectrum_carries_faces_in_caller_numbering():
    V, F = icosphere(2)
    V2 = np.concatenate([[[9.0, 9.0, 9.0]], V])  # an unreferenced vertex first
    s = o3dheat.eigensolve((V2, F + 1), k=5)
    assert np.array_equal(s.faces, F + 1) and s.n == len(V2)
