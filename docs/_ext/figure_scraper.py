"""A sphinx-gallery image scraper for matplotlib Figures made without pyplot.

o3dheat.visualization.plot returns ``matplotlib.figure.Figure`` objects that pyplot does not know (no GUI
backend, no global state), so sphinx-gallery's own matplotlib scraper, which asks pyplot for its
figures, misses them. This one saves every Figure that a code block leaves in the example's
namespace (as a variable, or in a list, tuple or dict variable), once, in the order they appear,
then hands over to the matplotlib scraper for any pyplot figures.
"""

from sphinx_gallery.scrapers import figure_rst, matplotlib_scraper

_DONE = "_o3dheat_scraped"


def _figures(value):
    from matplotlib.figure import Figure

    if isinstance(value, Figure):
        yield value
    elif isinstance(value, (list, tuple)):
        for v in value:
            if isinstance(v, Figure):
                yield v
    elif isinstance(value, dict):
        for v in value.values():
            if isinstance(v, Figure):
                yield v


def scrape(block, block_vars, gallery_conf, **kwargs):
    """Save the new Figures of the example's namespace; return their reST."""
    paths = []
    iterator = block_vars["image_path_iterator"]
    for value in list(block_vars["example_globals"].values()):
        for fig in _figures(value):
            if getattr(fig, _DONE, False):
                continue
            path = next(iterator)
            fig.savefig(path, dpi=110)
            setattr(fig, _DONE, True)
            paths.append(path)
    rst = figure_rst(paths, gallery_conf["src_dir"]) if paths else ""
    return rst + matplotlib_scraper(block, block_vars, gallery_conf, **kwargs)
