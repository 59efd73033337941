"""Helpers of the visualization tests: the renderer marker and reading pictures."""

import numpy as np
from conftest import torus

import o3dheat


def pixels(img, color):
    """Pixels close to a pure colour ("red", "blue", "green"): the critical points' markers."""
    r, g, b = (img[..., i].astype(int) for i in range(3))
    return int({"red": (r > 120) & (g < 60) & (b < 60), "blue": (b > 120) & (r < 60) & (g < 60),
                "green": (g > 60) & (r < 40) & (b < 40)}[color].sum())


def not_blank(path):
    from matplotlib.image import imread

    img = imread(path)[..., :3]
    return img.std() > 0.05 and np.any(img < 0.95, axis=2).mean() > 0.02


def torus_tracks(t=(0.0, 0.05, 0.1, 0.2, 0.4)):
    V, F = torus(1.0, 0.4, 40, 20)
    rng = np.random.default_rng(1)
    f = V[:, 0] + 0.3 * V[:, 2] + 0.05 * rng.standard_normal(len(V))
    t = np.asarray(t)
    Ft = o3dheat.heat_flow((V, F), f, t)
    return (V, F), Ft, o3dheat.track_critical_points((V, F), Ft, t)
