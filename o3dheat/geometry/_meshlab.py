"""pymeshlab's remeshing as the resamplings call it, and the bound on the faces it may make:
:func:`meshset`, :func:`isotropic`, :func:`faces_at`, :func:`bound_faces`, :func:`area` (plain
names, shared by :mod:`o3dheat.geometry.sampling`)."""

from __future__ import annotations

import numpy as np

from o3dheat import checks
from o3dheat.errors import MeshError

__all__ = ["isotropic", "meshset", "faces_at", "bound_faces", "area"]


def isotropic(ms, pymeshlab, length, iterations, selected):
    """``pymeshlab``'s isotropic explicit remeshing with every parameter given (its defaults, but the
    target length, iterations and selection): pymeshlab was seen to reuse a previous call's
    ``selectedonly=True``, so nothing is left to what an earlier call set."""
    ms.meshing_isotropic_explicit_remeshing(
        iterations=iterations, adaptive=False, selectedonly=selected, targetlen=pymeshlab.PureValue(length),
        featuredeg=30.0, checksurfdist=True, maxsurfdist=pymeshlab.PercentageValue(1.0), splitflag=True,
        collapseflag=True, swapflag=True, smoothflag=True, reprojectflag=True)


def meshset(V, F):
    """A pymeshlab MeshSet holding ``(V, F)``, and the pymeshlab module (imported here: 0.5 s)."""
    import pymeshlab

    ms = pymeshlab.MeshSet()
    ms.add_mesh(pymeshlab.Mesh(np.asarray(V, np.float64), np.asarray(F, np.int32)))
    return ms, pymeshlab


def faces_at(area, length):
    """The faces of an ``area`` covered by equilateral triangles of side ``length``."""
    return area / (np.sqrt(3) / 4 * length**2)


def bound_faces(faces, max_faces, what):
    """Refuse, before pymeshlab starts, a remeshing estimated to make more than ``max_faces``
    faces: pymeshlab gives no estimate and cannot be interrupted."""
    max_faces = checks.count(max_faces, "max_faces", maximum=2**62)
    if faces > max_faces:
        raise MeshError(f"{what} would make about {faces:.3g} faces (the area over an equilateral triangle's "
                        f"at the target edge length), more than max_faces={max_faces}: use a longer edge length, "
                        "or raise max_faces")


def area(V, F):
    """The area of the triangles ``F`` of ``V``."""
    return 0.5 * float(np.linalg.norm(np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]]), axis=1).sum())
