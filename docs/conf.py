"""Sphinx configuration of the o3dheat documentation site (built by scripts/docs.sh)."""

import os
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE / "_ext"))
os.environ.setdefault("MPLBACKEND", "Agg")        # headless: no display on build machines

import o3dheat  # noqa: E402

project = "o3dheat"
author = "o3dheat developers"
copyright = "2026, o3dheat developers"
release = version = o3dheat.__version__

extensions = [
    "sphinx.ext.autodoc",
    "sphinx.ext.mathjax",
    "sphinx-mathjax-offline",       # MathJax 3 copied into _static/mathjax: formulas render offline
    "numpydoc",
    "cli_reference",                # docs/_ext: the command reference from its parser
    "sphinx_gallery.gen_gallery",
    "myst_parser",                  # docs/details/*.md: the README's long sections, as written
]
source_suffix = {".rst": "restructuredtext", ".md": "markdown"}
myst_heading_anchors = 3

exclude_patterns = ["_build", "_ext", "examples/GALLERY_HEADER.rst", "**.ipynb_checkpoints"]
templates_path = []
default_role = "literal"          # `x` is code, as in the README
nitpicky = False

# --- API reference: autodoc + numpydoc --------------------------------------------------------
autodoc_default_options = {"members": True, "member-order": "bysource"}
autodoc_typehints = "none"        # the numpydoc Parameters sections say the types
autodoc_preserve_defaults = True  # signatures show `k=100`, `times=None`, not evaluated objects
numpydoc_show_class_members = False       # autodoc lists the members; no duplicate tables
numpydoc_class_members_toctree = False
numpydoc_xref_param_type = False
numpydoc_validation_checks = set()

# --- gallery: examples run at build time, their figures shown ----------------------------------
sphinx_gallery_conf = {
    "examples_dirs": "examples",
    "gallery_dirs": "auto_examples",
    "filename_pattern": r"/plot_",           # run every plot_*.py
    "image_scrapers": ("figure_scraper.scrape",),
    "download_all_examples": False,
    "remove_config_comments": True,
    "within_subsection_order": "FileNameSortKey",
    "abort_on_example_error": True,
    "only_warn_on_example_error": False,
    "show_memory": False,
    "min_reported_time": 1,
    "write_computation_times": False,
}

# --- HTML ------------------------------------------------------------------------------------
html_theme = "pydata_sphinx_theme"
html_title = f"o3dheat {release}"
html_theme_options = {
    "navigation_with_keys": False,
    "show_toc_level": 2,
    "secondary_sidebar_items": ["page-toc"],
    "footer_start": ["copyright"],
    "footer_end": [],
}
html_static_path = []
# The formulas' MathJax is served from the site itself (sphinx-mathjax-offline sets mathjax_path
# to _static/mathjax/tex-chtml.js and copies it there): Sphinx's default is a CDN URL, and a site
# read offline (this one is built and read without network) then shows raw TeX.
html_show_sourcelink = False
html_copy_source = False


def _undocumented_data(app, docname, source):
    """Append a ``py:data`` entry (name and value) for each constant of a module's ``__all__``
    that has no ``#:`` comment: autodoc documents module data only when it has one (else it would
    show the docstring of the value's type), and every public name belongs on the page."""
    if not docname.startswith("api/"):
        return
    import importlib
    import inspect

    from sphinx.pycode import ModuleAnalyzer

    modname = docname[len("api/"):]
    try:
        module = importlib.import_module(modname)
        documented = ModuleAnalyzer.for_module(modname).find_attr_docs()
    except Exception:  # not a module page
        return
    if hasattr(module, "__path__"):  # a stage's page lists its modules, not its members
        return
    names = [n for n in getattr(module, "__all__", ())
             if not (inspect.isroutine(getattr(module, n)) or inspect.isclass(getattr(module, n))
                     or inspect.ismodule(getattr(module, n))) and ("", n) not in documented]
    if names:
        entries = []
        for n in names:
            value = repr(getattr(module, n))
            value = value if len(value) <= 120 else value[:117] + "..."
            entries.append(f"\n.. py:data:: {n}\n   :module: {modname}\n   :value: {value}\n")
        source[0] += "\n" + "".join(entries)


def _section(env, pagename):
    """The top-level section (a page of the root toctree) that ``pagename`` belongs to, or None
    (the root page itself, or a page outside the toctrees: genindex, search)."""
    root = env.config.root_doc
    parent = {child: doc for doc, children in env.toctree_includes.items() for child in children}
    page, seen = pagename, set()
    while page in parent and page not in seen:
        seen.add(page)
        if parent[page] == root:
            return page
        page = parent[page]
    return None


def _hide_empty_navigation(app, pagename, templatename, context, doctree):
    """No primary sidebar on a page whose section has no sub-pages (install, conventions, paper,
    cli): pydata's "Section Navigation" lists a section's sub-pages, and these sections have none,
    so it showed an empty column (the theme drops it by itself on the root page only: with
    ``sidebar_includehidden`` on, its default, it does not look whether a section has sub-pages).
    An empty ``sidebars`` makes the theme hide the column on wide screens (it keeps it for the
    header's links on narrow ones)."""
    section = _section(app.env, pagename)
    if section is not None and not app.env.toctree_includes.get(section):
        context["sidebars"] = []


def setup(app):
    """Sphinx's hook for this project's own handlers (conf.py as a local extension)."""
    app.connect("source-read", _undocumented_data)
    app.connect("html-page-context", _hide_empty_navigation)
