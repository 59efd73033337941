"""o3dheat.topology.levelsets: level sets as line segments."""


import numpy as np
import pytest
from conftest import icosphere

import o3dheat


def test_level_sets_of_the_height_on_a_sphere():
    V, F = icosphere(3)
    ls = o3dheat.level_sets((V, F), V[:, 2], values=[0.0, 0.5])
    P, L = np.asarray(ls.points), np.asarray(ls.lines)
    assert len(L) > 0 and np.all(np.isin(np.round(P[:, 2], 12), [0.0, 0.5]))
    # each level set is a closed curve: every point is the end of exactly two segments
    assert np.all(np.bincount(L.reshape(-1), minlength=len(P)) == 2)
    length = np.linalg.norm(P[L[:, 0]] - P[L[:, 1]], axis=1)
    eq = np.abs(P[L[:, 0], 2]) < 1e-12
    assert abs(length[eq].sum() - 2 * np.pi) < 0.05  # the equator of the unit sphere
    assert len(o3dheat.level_sets((V, F), V[:, 2], count=5).lines) > len(L)


def test_level_sets_bad_input():
    V, F = icosphere(1)
    for kwargs in (dict(values=[np.nan]), dict(count=0), dict(values=[0.0], count=3)):
        with pytest.raises(o3dheat.MeshError):
            o3dheat.level_sets((V, F), V[:, 2], **kwargs)
    assert len(o3dheat.level_sets((V, F), V[:, 2], values=[5.0]).lines) == 0
