"""
Sphinx configuration of the cdr_translator docs (built as rosdoc2 builds a Python package's).

``python -m sphinx -W --keep-going -b html docs OUT`` builds them; the Markdown pages are
read by MyST, the API reference is generated from the docstrings by autodoc, and a broken
link, reference or docstring is an error (``-W``). tests/packaging/test_docs_build.py runs it.
"""

from pathlib import Path
import sys

DOCS = Path(__file__).resolve().parent
# The checkout documented is the one these docs are in, whatever else is installed. rosdoc2
# runs this file from a copy of docs/ in its build folder inside the package: the checkout is
# then the nearest folder above that holds package.xml.
CHECKOUT = next((folder for folder in DOCS.parents if (folder / 'package.xml').is_file()),
                DOCS.parent)
sys.path[:0] = [str(CHECKOUT), str(DOCS / '_ext')]

project = 'cdr_translator'
author = 'cdr_translator authors'
copyright = 'cdr_translator authors'  # noqa: A001 (the name Sphinx reads)

extensions = ['myst_parser', 'sphinx.ext.autodoc', 'cdr_docs']
source_suffix = {'.md': 'markdown', '.rst': 'restructuredtext'}
root_doc = 'index'
exclude_patterns = ['_build', '_ext']

# Markdown: GitHub's heading anchors (page.md#a-heading), $...$ maths off (prices, units)
myst_heading_anchors = 3
myst_enable_extensions = ['colon_fence', 'deflist']

# API reference: the public names, in source order, with their types in the description
autodoc_member_order = 'bysource'
# defaults as written (DEFAULT_PARAMS_PATH), not as evaluated on the building machine
autodoc_preserve_defaults = True
autodoc_typehints = 'description'
autodoc_typehints_description_target = 'documented_params'
autodoc_default_options = {'members': True, 'show-inheritance': True}

html_theme = 'alabaster'
html_title = 'cdr_translator'
html_theme_options = {'description': 'Cosserat-rod kinestatics of a continuum delta robot leg',
                      'fixed_sidebar': True}
