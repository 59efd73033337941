"""The README's Python examples run as written (the README stays true)."""

import re
from pathlib import Path

import pytest

README = Path(__file__).resolve().parents[1] / "README.md"


def _python_blocks():
    """The README's ```python blocks, in order."""
    return re.findall(r"```python\n(.*?)```", README.read_text(), re.S)


def test_readme_has_the_script_and_the_chain_blocks():
    blocks = _python_blocks()
    assert len(blocks) >= 2
    assert any("Chain(" in b for b in blocks) and any("eigensolve(" in b for b in blocks)


@pytest.mark.parametrize("index", range(len(_python_blocks())))
def test_each_readme_python_block_runs_on_its_own(index, tmp_path):
    """Each block runs as written in a fresh interpreter, with nothing from the blocks above it (a
    reader copies one block: the chain block once used the `mesh` of the block before), and calls
    nothing deprecated (a DeprecationWarning attributed to the block's own code is an error)."""
    import os
    import subprocess
    import sys

    block = _python_blocks()[index]
    run = subprocess.run([sys.executable, "-W", "error::DeprecationWarning:__main__", "-c", block], cwd=tmp_path,
                         capture_output=True, text=True, timeout=600, env={**os.environ, "MPLBACKEND": "Agg"})
    assert run.returncode == 0, f"README block {index + 1} failed on its own:\n{block}\n{run.stderr}"
    written = {p.name for p in tmp_path.iterdir()}
    if "Chain(" in block:
        assert {"out.ply", "chain.toml"} <= written
    if "write_mesh(" in block:
        assert any(name.endswith(".ply") for name in written)


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


def test_the_pip_only_fallback_reads_the_dependency_lists():
    """setup.sh's pip-only fallback (no scikit-sparse) reads pyproject's lists with a script of
    its own: its regex missed the two-line dev list (None.group raised, setup died)."""
    import re
    import subprocess
    import sys

    root = Path(__file__).resolve().parents[1]
    sh = (root / "scripts" / "setup.sh").read_text()
    code = re.search(r"deps=\$\(\"\$py\" - <<'PY'\n(.*?)\nPY\n", sh, re.S).group(1)
    out = subprocess.run([sys.executable, "-c", code], cwd=root, capture_output=True, text=True, timeout=60)
    assert out.returncode == 0, out.stderr
    deps = out.stdout.split()
    assert "cholespy>=1.0" in deps and "pytest>=7" in deps and not any(d.startswith("scikit-sparse") for d in deps)
