"""Sphinx configuration of hftrace's documentation (``make docs``).

The pages are the Markdown files of docs/ (read by myst-parser), an API reference that
autosummary generates from the numpydoc docstrings of every name in ``algos.__all__`` and
``datasets_gen.__all__``, and a gallery (sphinx-gallery) of the scripts in
examples/gallery/, which run at build time.
"""
import os
import shutil
import sys

DOCS = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(DOCS)
sys.path.insert(0, ROOT)

sys.path.insert(0, DOCS)
import api_reference  # noqa: E402

project = "hftrace"
author = "hftrace developers"
copyright = "hftrace developers"

extensions = [
    "myst_parser",
    "numpydoc",
    "sphinx.ext.autodoc",
    "sphinx.ext.autosummary",
    "sphinx.ext.mathjax",
    "sphinx_gallery.gen_gallery",
]

source_suffix = {".rst": "restructuredtext", ".md": "markdown"}
root_doc = "index"
templates_path = ["_templates"]
exclude_patterns = ["_build", "api/generated/*.md", "auto_examples/*.ipynb",
                    "auto_examples/*.py", "auto_examples/*.zip", "auto_examples/*.md5",
                    "auto_examples/*.json"]

# Markdown: heading anchors for in-page links ([text](#section)), dollar maths.
myst_heading_anchors = 3
myst_enable_extensions = ["dollarmath"]

# The Markdown pages also read well on a repository browser, so they link to source files,
# reports and the README by relative path; those targets are not pages of this site (their
# existence is checked by tests/project/test_docs.py instead).
suppress_warnings = ["myst.xref_missing"]

autosummary_generate = True
autodoc_default_options = {"members": False}
autodoc_typehints = "none"
numpydoc_show_class_members = False
numpydoc_class_members_toctree = False
numpydoc_validation_checks = set()

html_theme = "pydata_sphinx_theme"
html_title = "hftrace"
html_theme_options = {"navigation_with_keys": False, "show_toc_level": 2,
                      "header_links_before_dropdown": 4}
html_static_path = []

sphinx_gallery_conf = {
    "examples_dirs": [os.path.join(ROOT, "examples", "gallery")],
    "gallery_dirs": ["auto_examples"],
    "filename_pattern": r"/plot_",
    "download_all_examples": False,
    "remove_config_comments": True,
    "abort_on_example_error": True,
    "within_subsection_order": "FileNameSortKey",
    "image_scrapers": ("matplotlib",),
}


api_reference.write(DOCS)
# the gallery is rebuilt from its sources every time: no page of a removed example remains
shutil.rmtree(os.path.join(DOCS, "auto_examples"), ignore_errors=True)
