"""Files: mesh reading and writing (one READERS/WRITERS table), atomic writes, TOML, sample meshes.

Entry points: :func:`~o3dheat.io.meshes.read_mesh`, :func:`~o3dheat.io.meshes.read_geometry`,
:func:`~o3dheat.io.meshes.write_mesh`, :func:`~o3dheat.io.meshes.write_geometry`
(:mod:`o3dheat.io.meshes`), :func:`~o3dheat.io.files.atomic_write`,
:func:`~o3dheat.io.files.atomic_write_text` (:mod:`o3dheat.io.files`),
:func:`~o3dheat.io.toml.read_toml` (:mod:`o3dheat.io.toml`), :func:`~o3dheat.io.samples.sample_mesh`,
:func:`~o3dheat.io.samples.default_mesh`, :func:`~o3dheat.io.samples.bumpy_torus`
(:mod:`o3dheat.io.samples`)."""

from .files import atomic_write, atomic_write_text, read_regular
from .meshes import READERS, WRITERS, read_geometry, read_mesh, write_geometry, write_mesh
from .samples import SAMPLES, bumpy_torus, default_mesh, sample_mesh
from .toml import read_toml

# isort: split
# the modules, as attributes of the package
from . import files, meshes, samples, toml  # noqa: E402

__all__ = ["READERS", "WRITERS", "atomic_write", "atomic_write_text", "read_regular", "read_geometry", "read_mesh", "read_toml",
           "write_geometry", "write_mesh", "SAMPLES", "bumpy_torus", "default_mesh", "sample_mesh",
           "files", "meshes", "samples", "toml"]
