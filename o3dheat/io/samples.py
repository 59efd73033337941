"""Sample meshes usable offline: :func:`sample_mesh`, :func:`default_mesh`, :func:`bumpy_torus`.

The samples are closed 2-manifolds shipped inside pymeshlab (a required dependency), at
``pymeshlab/tests/sample_meshes/`` (:data:`SAMPLES`): the Stanford Bunny -- courtesy of the
Stanford 3D Scanning Repository --, an airplane and a bone. When pymeshlab's bunny is absent the
default mesh is a procedural surface (a bumpy torus). Nothing is downloaded.
"""

from __future__ import annotations

import importlib.resources
from typing import TYPE_CHECKING

import numpy as np

from o3dheat.errors import MeshError

from .meshes import read_mesh

if TYPE_CHECKING:  # Open3D is imported when a mesh is made (1.5 s): for annotations only
    import open3d as o3d

__all__ = ["SAMPLES", "default_mesh", "sample_mesh", "bumpy_torus"]

#: sample name -> file among pymeshlab's sample meshes: closed 2-manifolds (used offline by the studies)
SAMPLES = {"bunny": "bunny.obj", "airplane": "airplane.obj", "bone": "bone.ply", "cow": "cow.obj"}


def default_mesh() -> tuple[o3d.t.geometry.TriangleMesh, str]:
    """The embedded default mesh and its name.

    Returns
    -------
    mesh : o3d.t.geometry.TriangleMesh
        The Stanford Bunny shipped with pymeshlab (28k vertices, genus 0), or a procedural bumpy
        torus when pymeshlab's sample file is absent.
    name : str

    Examples
    --------
    >>> import o3dheat.io.samples as d
    >>> mesh, name = d.default_mesh()
    >>> name in ("bunny", "bumpy torus")
    True
    """
    import open3d as o3d

    try:
        path = importlib.resources.files("pymeshlab") / "tests" / "sample_meshes" / "bunny.obj"
        if path.is_file():
            legacy = o3d.io.read_triangle_mesh(str(path))
            if len(legacy.triangles):
                return o3d.t.geometry.TriangleMesh.from_legacy(legacy), "bunny"
    except (ModuleNotFoundError, OSError):
        pass
    return bumpy_torus(), "bumpy torus"


def sample_mesh(name: str) -> o3d.t.geometry.TriangleMesh:
    """A mesh shipped with an installed package, usable offline: "bunny", "airplane", "bone", "cow"
    (pymeshlab's samples) or "torus" (:func:`bumpy_torus`).

    Parameters
    ----------
    name : str
        One of :data:`SAMPLES`, or "torus".

    Returns
    -------
    o3d.t.geometry.TriangleMesh
        Unreferenced vertices removed.

    Raises
    ------
    MeshError
        Unknown name, or pymeshlab's sample file missing.

    Examples
    --------
    >>> import o3dheat.io.samples as d
    >>> len(d.sample_mesh("airplane").triangle.indices)
    10796
    """
    import open3d as o3d

    if name == "torus":
        return bumpy_torus()
    if name not in SAMPLES:
        raise MeshError(f"unknown sample mesh {name!r}: use one of {', '.join([*SAMPLES, 'torus'])}")
    path = importlib.resources.files("pymeshlab") / "tests" / "sample_meshes" / SAMPLES[name]
    if name == "cow" and path.is_file():  # Open3D's OBJ reader merges two coincident vertices of the cow that
        legacy = read_mesh(path).to_legacy()  # have fans of their own (a pinched vertex): o3dheat's keeps them
    else:
        legacy = o3d.io.read_triangle_mesh(str(path)) if path.is_file() else o3d.geometry.TriangleMesh()
    if len(legacy.triangles) == 0:
        raise MeshError(f"pymeshlab's sample {SAMPLES[name]} is not installed")
    legacy.remove_unreferenced_vertices()
    return o3d.t.geometry.TriangleMesh.from_legacy(legacy)


def bumpy_torus(radial: int = 96, tubular: int = 48) -> o3d.t.geometry.TriangleMesh:
    """A procedural torus with bumps (no files needed).

    Parameters
    ----------
    radial, tubular : int
        Resolution around the ring and around the tube.

    Returns
    -------
    o3d.t.geometry.TriangleMesh

    Examples
    --------
    >>> import o3dheat.io.samples as d
    >>> len(d.bumpy_torus(32, 16).vertex.positions)
    512
    """
    import open3d as o3d

    m = o3d.t.geometry.TriangleMesh.create_torus(1.0, 0.4, radial, tubular, float_dtype=o3d.core.float64)
    V = m.vertex.positions.numpy()
    u = np.arctan2(V[:, 1], V[:, 0])
    c = np.stack([np.cos(u), np.sin(u), 0 * u], 1)
    d = V - c
    V = c + d * (1 + 0.15 * np.sin(5 * u) * np.cos(3 * np.arctan2(d[:, 2], np.sum(d * c, 1))))[:, None]
    m.vertex.positions = o3d.core.Tensor(V)
    return m
