"""The documentation rule: every public function, class and method has a numpydoc ``Examples``
section (run as a doctest by ``--doctest-modules``), and the site's API pages list every module.

Public means: the names of each module's ``__all__`` (``o3dheat.*``; ``o3dheat_filters.*``, whose
modules have no ``__all__``, contribute the classes and functions they define; modules whose name
starts with ``_`` are the package's internal helpers, not public), and, for each
public class, the functions, class methods and static methods defined in its body whose names do
not start with ``_``. Properties and data are attributes: the class's example shows them.
Examples marked ``# doctest: +SKIP`` count (a Dask cluster of worker processes is too slow for
the test suite).
"""

import importlib
import inspect
import pkgutil
import re
from pathlib import Path

import o3dheat
import o3dheat_filters

DOCS = Path(__file__).resolve().parents[1] / "docs"
EXAMPLES = re.compile(r"^Examples\n-{8,}\n", re.M)


def modules():
    names = [m.name for m in pkgutil.walk_packages(o3dheat.__path__, prefix="o3dheat.")
             if not any(part.startswith("_") for part in m.name.split("."))]
    names += [f"o3dheat_filters.{m.name}" for m in pkgutil.iter_modules(o3dheat_filters.__path__)
              if not m.name.startswith("_")]
    return sorted(names)


def public_names(module):
    names = getattr(module, "__all__", None)
    if names is None:
        names = [n for n, o in vars(module).items() if not n.startswith("_")
                 and (inspect.isclass(o) or inspect.isfunction(o)) and o.__module__ == module.__name__]
    return names


def documented():
    """[(qualified name, object)]: every public function, class and method, once each."""
    seen, out = set(), []
    for mod_name in modules():
        module = importlib.import_module(mod_name)
        for name in public_names(module):
            obj = getattr(module, name)
            if not (inspect.isclass(obj) or inspect.isfunction(obj)) or id(obj) in seen:
                continue
            seen.add(id(obj))
            out.append((f"{mod_name}.{name}", obj))
            if inspect.isclass(obj):
                for attr, value in vars(obj).items():
                    if isinstance(value, (staticmethod, classmethod)):
                        value = value.__func__
                    if not attr.startswith("_") and inspect.isfunction(value):
                        out.append((f"{mod_name}.{name}.{attr}", value))
    return out


def test_every_public_function_class_and_method_has_an_example():
    items = documented()
    missing = [name for name, obj in items if not EXAMPLES.search(inspect.getdoc(obj) or "")]
    assert not missing, f"{len(missing)} of {len(items)} public names have no Examples section:\n  " + "\n  ".join(missing)


def test_the_api_reference_lists_every_module():
    # `automodule` documents every name of the module's __all__ (conf.py: members by default)
    api = "\n".join(p.read_text() for p in (DOCS / "api").glob("*.rst"))
    absent = [m for m in modules() if not re.search(rf"^\.\. automodule:: {re.escape(m)}$", api, re.M)]
    assert not absent, f"modules missing from docs/api/: {absent}"



# --- the site works offline and has no empty navigation column (issue 22) ---------------------
#
# A small site built with docs/conf.py (the gallery left out: its examples take minutes) checks the
# configuration itself; the checks of docs/_build/html run when the full site has been built
# (scripts/docs.sh).

import os  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402

import pytest  # noqa: E402

BUILT = DOCS / "_build" / "html"
REMOTE_ASSET = re.compile(r"""<(?:script|link)\b[^>]*\b(?:src|href)=["'](?:https?:)?//""", re.I)
MATH = re.compile(r'class="math[ "]')


def _pages(root):
    return sorted(p for p in root.rglob("*.html") if "_static" not in p.parts)


def _navigation(html):
    """The primary sidebar's "Section Navigation" block, or None."""
    nav = re.search(r'<nav class="bd-docs-nav bd-links".*?</nav>', html, re.S)
    return nav.group(0) if nav else None


def _mathjax_src(html):
    return re.findall(r'<script[^>]*src="([^"?]*tex[^"?]*\.js)(?:\?[^"]*)?"', html)  # Sphinx may add ?v=digest


@pytest.fixture(scope="module")
def mini_site(tmp_path_factory):
    pytest.importorskip("sphinx")
    src = tmp_path_factory.mktemp("site")
    (src / "conf.py").write_text(
        "import runpy\n"
        f"conf = runpy.run_path({str(DOCS / 'conf.py')!r})\n"
        "globals().update({k: v for k, v in conf.items() if not k.startswith('__')})\n"
        "extensions = [e for e in extensions if e != 'sphinx_gallery.gen_gallery']\n")
    (src / "index.rst").write_text("Home\n====\n\n.. toctree::\n\n   flat\n   section/index\n")
    (src / "flat.rst").write_text("Flat\n====\n\nA formula :math:`K_t = X D_t X^\\top B`.\n\n"
                                  ".. math::\n\n   t_\\text{paper} = 2 t_\\text{peer}\n")
    (src / "section").mkdir()
    (src / "section" / "index.rst").write_text("Section\n=======\n\n.. toctree::\n\n   child\n")
    (src / "section" / "child.rst").write_text("Child\n=====\n\nText.\n")
    out = src / "_build"
    run = subprocess.run([sys.executable, "-m", "sphinx", "-W", "-q", "-b", "html", str(src), str(out)],
                         capture_output=True, text=True, env={**os.environ, "MPLBACKEND": "Agg"})
    assert run.returncode == 0, run.stderr
    return out


def test_mathjax_is_served_by_the_site(mini_site):
    html = (mini_site / "flat.html").read_text()
    assert MATH.search(html)
    srcs = _mathjax_src(html)
    assert srcs and all(not re.match(r"(https?:)?//", s) for s in srcs), srcs
    assert (mini_site / srcs[0].split("?")[0]).is_file()
    assert (mini_site / "_static" / "mathjax" / "output" / "chtml" / "fonts" / "woff-v2").is_dir()
    remote = [p.name for p in _pages(mini_site) if REMOTE_ASSET.search(p.read_text())]
    assert not remote, f"pages loading scripts or styles from the network: {remote}"


def test_no_empty_navigation_column(mini_site):
    flat, child = (mini_site / "flat.html").read_text(), (mini_site / "section" / "child.html").read_text()
    assert _navigation(flat) is None and "Collapse Sidebar" not in flat
    assert re.search(r'id="pst-primary-sidebar" class="[^"]*hide-on-wide', flat)
    # a section with pages keeps its navigation
    assert "<a " in (_navigation(child) or "")
    assert not re.search(r'id="pst-primary-sidebar" class="[^"]*hide-on-wide', child)


built = pytest.mark.skipif(not (BUILT / "index.html").is_file(), reason="site not built (scripts/docs.sh)")


@built
def test_built_site_loads_nothing_from_the_network():
    pages = _pages(BUILT)
    remote = [str(p.relative_to(BUILT)) for p in pages if REMOTE_ASSET.search(p.read_text())]
    assert not remote, f"pages loading scripts or styles from the network: {remote}"
    with_math = [p for p in pages if MATH.search(p.read_text())]
    assert any(p.name == "conventions.html" for p in with_math)
    for p in with_math:
        srcs = _mathjax_src(p.read_text())
        assert srcs and (p.parent / srcs[0].split("?")[0]).resolve().is_file(), p


@built
def test_built_site_has_no_empty_navigation_column():
    empty = []
    for p in _pages(BUILT):
        html = p.read_text()
        nav = _navigation(html)
        if nav is not None and "<a " not in nav:
            empty.append(str(p.relative_to(BUILT)))
    assert not empty, f"pages with an empty Section Navigation: {empty}"
    for name in ("cli", "conventions", "paper", "install"):
        assert "Section Navigation" not in (BUILT / f"{name}.html").read_text(), name
    assert "Section Navigation" in (BUILT / "details" / "topology.html").read_text()


# --- the pages' claims agree with their own tables and data (issue 22) -------------------------

def _table(text, first_cell):
    """Rows (lists of cells) of the Markdown table rows whose first cell is one of first_cell."""
    rows = [[c.strip() for c in line.strip().strip("|").split("|")] for line in text.splitlines()
            if line.startswith("|")]
    return [r for r in rows if r[0] in first_cell]


def test_topology_headline_states_both_ratios_from_the_table():
    text = (DOCS / "details" / "topology.md").read_text()
    head = [r.strip() for r in next(line for line in text.splitlines() if line.startswith("| mesh")).strip("|").split("|")]
    rows = _table(text, {"torus", "bunny"})
    assert len(rows) == 8
    n = head.index("n")
    per_stage, end_to_end = head.index("gudhi / o3dheat"), head.index("gudhi / (build + o3dheat)")
    prose = " ".join(text.split("| bunny | 1,000,002 | noisy")[1].split())   # the text after the table
    for big, label in ((True, "at 1M"), (False, "at 100k")):
        sel = [r for r in rows if (int(r[n].replace(",", "")) > 500_000) == big]
        e2e = [float(r[end_to_end].rstrip("x")) for r in sel]
        stage = [float(r[per_stage].rstrip("x")) for r in sel]
        assert f"{min(e2e):.2g}–{max(e2e):.2g}x" in prose, (label, e2e)
        assert f"{min(stage):.0f}–{max(stage):.0f}x" in prose, (label, stage)
    # the per-stage figure is never the headline on its own: it is named for what it times
    assert "end to end from the arrays" in prose and "per stage" in prose
    assert not re.search(r"persistence is \d+–\d+x faster than gudhi", prose)


def test_studies_page_states_the_kernels_per_resampling():
    pd = pytest.importorskip("pandas")
    text = " ".join((DOCS / "details" / "studies.md").read_text().split())
    d = pd.read_csv(DOCS / "study_paper.csv")
    h = d[d.descriptor == "smooth_height"]
    med = h.groupby(["resampling", "kernel"]).rel_l2.median().unstack()
    ratio = med[["lumped", "voronoi"]].div(med.weighted, axis=0)
    for resampling in ("decimate-50", "decimate-80"):
        v, lump = ratio.loc[resampling, "voronoi"], ratio.loc[resampling, "lumped"]
        assert f"by {v:.2f}x (Voronoi) to {lump:.2f}x (lumped)" in text, resampling
    rest = ratio.loc[["anisotropic", "jitter", "remesh"]].to_numpy()
    assert f"({rest.min():.2f}–{rest.max():.2f}x the weighted kernel's median)" in text
    per_mesh = h.groupby(["mesh", "resampling", "kernel"]).rel_l2.median().unstack()
    per_mesh = per_mesh[["lumped", "voronoi"]].div(per_mesh.weighted, axis=0)
    (mesh, _), top = per_mesh.max(axis=1).idxmax(), per_mesh.to_numpy().max()
    assert f"on the {mesh} by up to {top:.2f}x" in text
    torus = per_mesh.loc["torus"].loc[["decimate-50", "decimate-80"]].to_numpy()
    assert f"on the torus it trails ({torus.min():.2f}–{torus.max():.2f}x)" in text
    kind = h.groupby(["kind", "kernel"]).rel_l2.median().unstack()
    pooled = kind.loc["decimate"]
    assert f"hides this ({min(pooled.lumped, pooled.voronoi) / pooled.weighted:.2f}x)" in text
    assert f"{pooled.linear / pooled.weighted:.1f}x with the reference's scales" in text
    # "within 5%" is said of the pooled medians, not of every resampling
    for m in re.finditer(r"within 5%", text):
        assert "pooled" in text[m.start() - 80:m.end() + 80]


def test_readme_says_the_demo_counts_saddles_with_multiplicity():
    readme = " ".join((DOCS.parent / "README.md").read_text().split())
    assert re.search(r"\d+ critical points in the noisy input \([^)]*saddle counted with its multiplicity", readme)


def test_the_descriptors_study_page_quotes_the_shipped_table():
    """Issue 31: every number of "Which descriptor survives resampling" is the shipped CSV's, as
    scripts/study_descriptors.py prints it."""
    import importlib.util

    pytest.importorskip("pandas")
    spec = importlib.util.spec_from_file_location("study_descriptors", DOCS.parent / "scripts" / "study_descriptors.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    t, overall, per_kind, ratio = mod.tables(DOCS / "study_descriptors.csv")
    text = (DOCS / "details" / "studies.md").read_text()
    section = text[text.index("## Which descriptor survives resampling"):]
    flat = " ".join(section.split())
    assert f"{len(t)} rows" in flat
    for name, row in overall.drop(index="critical_points").iterrows():
        assert f"| {name} | " + " | ".join(f"{v:.3g}" for v in row) + " |" in section, name
    for d, kind in (("hks_density", "anisotropic"), ("wks", "anisotropic"), ("smooth_height", "anisotropic"),
                    ("hks_density", "jitter"), ("wks", "jitter"), ("smooth_height", "jitter")):
        assert f"{per_kind.loc[d, kind]:.3g}" in flat, (d, kind)
    for d in ("smooth_height", "diagram", "si_hks", "hks_density", "wks"):
        for k in ("lumped", "voronoi", "linear"):
            assert f"{ratio.loc[d, k]:.2f}x" in flat, (d, k)
    c = t[t["descriptor"] == "critical_points"].groupby("kernel")["rel_l2"]
    for k in ("weighted", "lumped", "voronoi", "linear"):
        assert f"{c.mean()[k]:.3f}" in flat and f"{round(100 * (c.apply(lambda s: (s > 0).mean()))[k])}%" in flat, k
