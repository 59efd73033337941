"""``.. o3dheat-cli::``: the ``o3dheat`` command's reference, generated from its argparse parser.

Each command gets a section whose body is exactly what ``o3dheat COMMAND --help`` prints (as a
literal block: help texts are plain text, not reStructuredText), so the page and the command can
never disagree.
"""

import os

from docutils import nodes
from docutils.statemachine import StringList
from sphinx.util.docutils import SphinxDirective
from sphinx.util.nodes import nested_parse_with_titles


def _subcommands(parser):
    import argparse

    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            return dict(action.choices)
    return {}


class CliReference(SphinxDirective):
    """The ``o3dheat-cli`` directive (no arguments, no content): one section per command."""

    has_content = False

    def run(self):
        """The sections, parsed from the ``--help`` texts of ``o3dheat`` and of each subcommand."""
        from o3dheat.cli import _parser

        old = os.environ.get("COLUMNS")
        os.environ["COLUMNS"] = "100"     # argparse wraps help to the terminal width
        try:
            parser = _parser()
            blocks = [("o3dheat", "o3dheat --help", parser.format_help())]
            for name, sub in _subcommands(parser).items():
                blocks.append((f"o3dheat {name}", f"o3dheat {name} --help", sub.format_help()))
        finally:
            if old is None:
                del os.environ["COLUMNS"]
            else:
                os.environ["COLUMNS"] = old
        lines = []
        for title, command, text in blocks:
            lines += [f"``{title}``", "-" * (len(title) + 4), "", ".. code-block:: text", ""]
            lines += ["   $ " + command] + ["   " + line if line else "" for line in text.rstrip().splitlines()]
            lines += [""]
        container = nodes.container()
        nested_parse_with_titles(self.state, StringList(lines, source="o3dheat.cli._parser()"), container)
        return container.children


def setup(app):
    """Sphinx extension entry point: registers the ``o3dheat-cli`` directive."""
    app.add_directive("o3dheat-cli", CliReference)
    return {"parallel_read_safe": True, "parallel_write_safe": True}
