"""TOML configuration files (filter chains, studies): :func:`read_toml`."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any

from o3dheat.errors import MeshError

from .files import read_regular

try:
    import tomllib
except ImportError:  # pragma: no cover - Python 3.10
    import tomli as tomllib

if TYPE_CHECKING:  # o3dheat.typing imports Open3D (1.5 s): for annotations only
    from o3dheat.typing import PathLike

__all__ = ["read_toml"]


def read_toml(path: PathLike) -> dict[str, Any]:
    r"""A TOML file as a dict.

    Parameters
    ----------
    path : str or Path
        The file (UTF-8 text).

    Returns
    -------
    dict

    Raises
    ------
    MeshError
        The file is not UTF-8 or not valid TOML; :class:`~o3dheat.errors.NoSuchFile` (also a
        ``FileNotFoundError``) when it is missing.
    OSError
        The file cannot be read (a folder, no permission): the file system's own error.

    Examples
    --------
    >>> import pathlib, tempfile
    >>> from o3dheat.io import read_toml
    >>> p = pathlib.Path(tempfile.mkdtemp()) / "chain.toml"
    >>> _ = p.write_text('[[filter]]\nname = "scalar"\n')
    >>> read_toml(p)
    {'filter': [{'name': 'scalar'}]}
    """
    path = Path(path)
    data = read_regular(path, "TOML file", limit=64 * 2**20)  # a FIFO or a device: refused, not waited on
    try:
        return tomllib.loads(data.decode("utf-8"))
    except RecursionError:
        raise MeshError(f"{path}: not valid TOML for o3dheat (nested too deeply)") from None
    except UnicodeDecodeError as e:
        raise MeshError(f"{path}: not UTF-8 text ({e.reason} at byte {e.start})") from e
    except tomllib.TOMLDecodeError as e:
        raise MeshError(f"{path}: not valid TOML ({e})") from e
