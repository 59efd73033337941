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
