"""Point-cloud operators of the filter SDK (:class:`o3dheat.pipelines.site.Site`): the shared Poisson surface, robust-laplacian's.

Entry points: :func:`reconstruction`, :func:`robust_operators`, :func:`robust_spectrum`.
"""

from __future__ import annotations

import hashlib

import numpy as np

from o3dheat.errors import MeshError
from o3dheat.geometry import mesh as meshes
from o3dheat.geometry import points
from o3dheat.spectral import cache, spectrum


def reconstruction(site):
    """The surface through a site's points, made once per point set and normals and shared by the
    steps of a chain (each step reads its own copy of the cloud: reconstructing it again cost a
    Poisson solve per step, and its repairs were reported at every step)."""
    meshes.check_points(site.P, planar=False)
    h = hashlib.sha256(np.ascontiguousarray(site.P).tobytes())
    if "normals" in site.attrs:
        h.update(np.ascontiguousarray(site.attrs["normals"].numpy(), dtype=np.float64).tobytes())
    return cache.memoized(("reconstruct", h.hexdigest()), lambda: points.reconstruct(site.out))


def robust_operators(P):
    meshes.check_points(P, planar=True, min_points=31, what="the point cloud (robust operators: 30 neighbours each)")
    try:  # an optional dependency (pip install robust-laplacian): imported when a filter asks for it
        import robust_laplacian
    except ImportError:
        raise MeshError("operators='robust' needs robust-laplacian: pip install robust-laplacian "
                        "(or use operators='reconstruct')") from None
    return robust_laplacian.point_cloud_laplacian(P)


def robust_spectrum(P, k):
    def compute():
        L, M = robust_operators(P)
        return spectrum.eigensolve_operators(L, M, k=min(k, len(P) - 2))

    key = ("robust", hashlib.sha256(np.ascontiguousarray(P, dtype=np.float64).tobytes()).hexdigest(), k)
    return cache.memoized(key, compute)
