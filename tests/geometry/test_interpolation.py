"""o3dheat.geometry.interpolation: functions moved between samplings (transfer, nearest)."""

import numpy as np
import pytest
from conftest import icosphere

import o3dheat
from o3dheat.geometry.interpolation import nearest, transfer
from o3dheat.geometry.sampling import decimate


def test_transfer_is_exact_for_linear_functions():
    V, F = icosphere(3)
    f = 2 * V[:, 0] - V[:, 1] + 0.5
    P = icosphere(2)[0] * 1.0  # points on the sphere, also vertices of the coarser sphere
    g = transfer(f, (V, F), P)
    assert np.allclose(g, 2 * P[:, 0] - P[:, 1] + 0.5, atol=1e-6)
    G = transfer(np.stack([f, -f], 1), (V, F), P)
    assert G.shape == (len(P), 2) and np.allclose(G[:, 1], -g)
    with pytest.raises(o3dheat.MeshError):
        transfer(f[:5], (V, F), P)
    assert nearest(f, V, V[:7] + 1e-9).tolist() == f[:7].tolist()


def test_transfer_far_from_the_origin_and_bad_values():
    """A georeferenced scan (5e6 m from the origin) transfers as well as at the origin; NaN values
    are refused, not propagated."""
    V, F = icosphere(3)
    f = 2 * V[:, 0] - V[:, 1] + 0.5
    P = icosphere(2)[0] * 1.0
    g = transfer(f, (V, F), P)
    offset = np.array([5e6, -3e6, 1e5])
    np.testing.assert_allclose(transfer(f, (V + offset, F), P + offset), g, atol=1e-7)
    bad = f.copy()
    bad[3] = np.nan
    with pytest.raises(o3dheat.MeshError, match="NaN"):
        transfer(bad, (V, F), P)


def test_transfer_is_the_identity_on_the_same_mesh():
    from conftest import irregular

    V, F = irregular()
    f = np.random.default_rng(2).standard_normal((len(V), 3))
    assert np.allclose(transfer(f, (V, F), (V, F)), f, atol=1e-10)
    from o3dheat.geometry.sampling import subdivide

    s = subdivide((V, F), 2)  # its vertices lie on the source surface: linear fields transfer exactly
    assert np.allclose(transfer(V, (V, F), s), s.V, atol=1e-12)
    r = decimate((V, F), reduction=0.5)  # off the surface: within the decimation's deviation
    assert np.allclose(transfer(V, (V, F), r), r.V, atol=0.02)
    assert np.allclose(transfer(r.V[:, 0], r, r.mesh), r.V[:, 0], atol=1e-10)


def test_transfer_to_non_finite_points_and_nearest_of_nothing_are_one_line_errors():
    """Issue 30: transfer to NaN/inf points gave IndexError 4294967295; nearest([], empty, V) an
    IndexError."""
    V, F = icosphere(2)
    for bad in (np.full((3, 3), np.nan), np.r_[V[:2], [[np.inf, 0, 0]]]):
        with pytest.raises(o3dheat.MeshError, match="NaN or infinite"):
            transfer(V[:, 2], (V, F), bad)
    with pytest.raises(o3dheat.MeshError, match="at least one"):
        nearest([], np.zeros((0, 3)), V)
    with pytest.raises(o3dheat.MeshError, match="finite"):
        nearest([1.0], [[np.nan, 0, 0]], V)


def test_transfer_map_made_once_moves_every_field_as_transfer_does():
    from o3dheat.geometry.interpolation import TransferMap, transfer_map

    V, F = icosphere(3)
    r = decimate((V, F), 0.6, vertex_map=False)
    move = transfer_map((V, F), r)
    assert isinstance(move, TransferMap) and move.corners.shape == move.weights.shape == (len(r.V), 3)
    np.testing.assert_allclose(move.weights.sum(axis=1), 1.0, rtol=0, atol=1e-12)
    assert (move.weights >= 0).all()
    f = np.c_[V[:, 0] ** 2, np.sin(3 * V[:, 1]), V[:, 2]]
    np.testing.assert_array_equal(move(f), transfer(f, (V, F), r))
    np.testing.assert_array_equal(move(f[:, 1]), transfer(f[:, 1], (V, F), r))
    with pytest.raises(o3dheat.MeshError, match="one row per source vertex"):
        move(f[:-1])
    bad = f[:, 0].copy()
    bad[7] = np.inf
    with pytest.raises(o3dheat.MeshError):
        move(bad)
