"""The README's Python examples run as written (the README stays true)."""

import re
from pathlib import Path

README = Path(__file__).resolve().parents[1] / "README.md"


def test_readme_python_blocks_run(tmp_path, monkeypatch):
    blocks = re.findall(r"```python\n(.*?)```", README.read_text(), re.S)
    assert len(blocks) >= 2
    monkeypatch.chdir(tmp_path)  # the examples write files
    namespace = {}
    for block in blocks:
        exec(compile(block, str(README), "exec"), namespace)
    assert (tmp_path / "out.ply").exists() and (tmp_path / "chain.toml").exists()


def test_version_and_licence_have_one_source():
    """Issue 23: __version__ comes from the package metadata (pyproject.toml), and the LICENSE file
    is the licence pyproject names."""
    from pathlib import Path

    import tomllib

    import o3dheat

    root = Path(__file__).resolve().parent.parent
    project = tomllib.loads((root / "pyproject.toml").read_text())["project"]
    assert o3dheat.__version__ == project["version"]
    assert project["license"] == "MIT" and (root / "LICENSE").read_text().startswith("MIT License")
    assert f"\"{project['version']}\"" not in (root / "o3dheat" / "__init__.py").read_text()
