"""Files: mesh reading and writing (one READERS/WRITERS table), atomic writes, TOML."""

from .meshes import (
    WRITERS,
    atomic_write,
    atomic_write_text,
    read_geometry,
    read_mesh,
    read_toml,
    write_geometry,
    write_mesh,
)

# isort: split
# the modules, as attributes of the package
from . import meshes  # noqa: E402

__all__ = ["WRITERS", "atomic_write", "atomic_write_text", "read_geometry", "read_mesh", "read_toml", "write_geometry", "write_mesh", "meshes"]
