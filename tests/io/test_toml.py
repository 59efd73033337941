"""o3dheat.io.toml: TOML files, decoding errors as MeshError, file-system errors as OSError."""

import pytest

import o3dheat


def test_non_utf8_toml_is_a_mesh_error(tmp_path):
    from o3dheat.io import read_toml
    p = tmp_path / "s.toml"
    p.write_bytes(b"name = \"\xff\xfe\"\n")
    with pytest.raises(o3dheat.MeshError, match="s.toml.*not UTF-8"):
        read_toml(p)


def test_unreadable_toml_is_the_file_systems_error(tmp_path):
    """Issue 23: "OSError stays OSError": a folder is the OSError open() raises; a missing file is
    a NoSuchFile, a FileNotFoundError naming it (and a MeshError, like every missing input)."""
    from o3dheat.io import read_toml
    with pytest.raises(FileNotFoundError, match="missing.toml"):
        read_toml(tmp_path / "missing.toml")
    with pytest.raises(IsADirectoryError):
        read_toml(tmp_path)


def test_a_deeply_nested_or_special_file_is_one_line_not_a_recursion_or_a_hang(tmp_path):
    """Issue 30: a chain TOML nested 10,000 levels gave a RecursionError; a FIFO would block."""
    import os

    from o3dheat.io import read_toml

    deep = tmp_path / "deep.toml"
    deep.write_text("a = " + "[" * 10000 + "]" * 10000 + "\n")
    with pytest.raises(o3dheat.MeshError, match="nested too deeply"):
        read_toml(deep)
    with pytest.raises(o3dheat.MeshError, match="nested too deeply"):
        o3dheat.filters.Chain.load(deep)
    os.mkfifo(tmp_path / "pipe.toml")
    with pytest.raises(o3dheat.MeshError, match="not a regular file \\(a FIFO\\)"):
        read_toml(tmp_path / "pipe.toml")
