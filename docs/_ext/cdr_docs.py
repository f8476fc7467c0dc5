"""
Sphinx helpers of the cdr_translator docs.

* ``command-help``: the ``--help`` text of a command, taken from the command itself
  (``cdr_translator solve``, ``msg_tools replay``), so that the reference cannot drift.
* Links from a page to a file outside the docs (``../../bench/results/targets.md``, a
  figure, a YAML file) become downloads: the generated reports stay where they are made
  and the built pages still reach them, while a link to a missing page is still an error.
"""

import contextlib
import importlib
import io
import os
from pathlib import Path
import re
from typing import Any, Dict, List

from docutils import nodes
from sphinx import addnodes
from sphinx.application import Sphinx
from sphinx.transforms import SphinxTransform
from sphinx.util.docutils import SphinxDirective

#: The program of each command name and the module whose ``main(argv)`` runs it.
PROGRAMS = {'cdr_translator': 'cdr_translator.cli', 'msg_tools': 'msg_tools.__main__'}
#: Width of the help texts (argparse reads it from COLUMNS).
HELP_COLUMNS = '92'
#: The checkout, whose absolute path a default in a help text would otherwise show.
ROOT = Path(__file__).resolve().parents[2]


def command_help(argv: List[str]) -> str:
    """Return what ``python -m PROGRAM ARGS --help`` prints."""
    module = importlib.import_module(PROGRAMS[argv[0]])
    output = io.StringIO()
    previous = os.environ.get('COLUMNS')
    os.environ['COLUMNS'] = HELP_COLUMNS
    try:
        with contextlib.redirect_stdout(output), contextlib.suppress(SystemExit):
            module.main([*argv[1:], '--help'])
    finally:
        if previous is None:
            del os.environ['COLUMNS']
        else:
            os.environ['COLUMNS'] = previous
    text = output.getvalue()
    if not text.startswith('usage:'):
        raise ValueError(f'{" ".join(argv)} --help printed no usage: {text[:200]!r}')
    # argparse may wrap a default path at a hyphen: match the checkout's path across a wrap
    wrapped = ''.join(re.escape(char) + (r'(?:\n *)?' if char == '-' else '')
                      for char in f'{ROOT}{os.sep}')
    return re.sub(wrapped, '', text)


class CommandHelp(SphinxDirective):
    """``command-help PROGRAM [SUBCOMMAND]``: the command's help as a literal block."""

    required_arguments = 1
    optional_arguments = 3

    def run(self) -> List[nodes.Node]:
        """Return the help text of the command named by the arguments."""
        text = command_help(list(self.arguments))
        block = nodes.literal_block(text, text)
        block['language'] = 'text'
        return [block]


class OutsideLinksToDownloads(SphinxTransform):
    """Turn a link to a Markdown file outside the docs into a download of that file."""

    default_priority = 5

    def apply(self, **kwargs: Any) -> None:
        """Replace each such pending reference by a download reference."""
        page_dir = Path(self.env.doc2path(self.env.docname)).resolve().parent
        for node in list(self.document.findall(addnodes.pending_xref)):
            if node.get('refdomain') != 'doc' or node.get('reftype') != 'myst':
                continue
            # a page outside the source folder has its absolute path, less .md, as docname
            target = Path(str(node['reftarget']) + '.md')
            if not (target.is_absolute() and target.is_file()):
                continue
            download = addnodes.download_reference(
                refdomain=None, reftype='myst', refdoc=self.env.docname,
                reftarget=os.path.relpath(target, page_dir), refexplicit=True)
            download.extend(node.children)
            node.replace_self(download)


def setup(app: Sphinx) -> Dict[str, Any]:
    """Register the directive and the transform."""
    app.add_directive('command-help', CommandHelp)
    app.add_transform(OutsideLinksToDownloads)
    return {'parallel_read_safe': True, 'parallel_write_safe': True}
